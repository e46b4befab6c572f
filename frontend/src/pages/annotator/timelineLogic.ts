// Pure timeline logic: frame <-> pixel mapping, edge dragging, in/out points, undo/redo of edits.

export interface Span {
  first_frame: number;
  last_frame: number;
}

export interface SegmentData extends Span {
  label_key: string;
}

/** Keep a frame inside 0..frameCount-1 (whole frames only). */
export function clampFrame(frame: number, frameCount: number): number {
  if (frameCount <= 0) return 0;
  return Math.min(Math.max(Math.round(frame), 0), frameCount - 1);
}

/** x in pixels of the left edge of a frame, for a lane `width` pixels wide. */
export function frameToX(frame: number, frameCount: number, width: number): number {
  return (frame / Math.max(frameCount, 1)) * width;
}

/** The frame under pixel x. */
export function xToFrame(x: number, frameCount: number, width: number): number {
  return clampFrame(Math.floor((x / Math.max(width, 1)) * frameCount), frameCount);
}

/** In and out points in either order -> an inclusive span, or null while one is missing. */
export function spanFromMarks(inPoint: number | null, outPoint: number | null): Span | null {
  if (inPoint === null || outPoint === null) return null;
  return { first_frame: Math.min(inPoint, outPoint), last_frame: Math.max(inPoint, outPoint) };
}

/** Move one edge of a span to `frame`; the other edge stays, and the span never inverts. */
export function dragEdge(
  span: Span,
  edge: "first" | "last",
  frame: number,
  frameCount: number,
): Span {
  const f = clampFrame(frame, frameCount);
  if (edge === "first") return { ...span, first_frame: Math.min(f, span.last_frame) };
  return { ...span, last_frame: Math.max(f, span.first_frame) };
}

/** Step the playhead by `delta` frames, clamped. */
export function step(frame: number, delta: number, frameCount: number): number {
  return clampFrame(frame + delta, frameCount);
}

export const SPEEDS = [0.25, 0.5, 1, 2, 4] as const;

export function nextSpeed(speed: number, direction: 1 | -1): number {
  const i = SPEEDS.indexOf(speed as (typeof SPEEDS)[number]);
  const j = Math.min(Math.max((i < 0 ? 2 : i) + direction, 0), SPEEDS.length - 1);
  return SPEEDS[j];
}

/** Frames to advance after `elapsedMs` of playback at `speed` (fractional frames carried). */
export function playbackAdvance(elapsedMs: number, fps: number, speed: number): number {
  return (elapsedMs / 1000) * fps * speed;
}

// -- undo / redo ----------------------------------------------------------------------------

/** An edit as the server saw it. Ids are server ids; re-creating a deleted segment gives it a
 * new id, which `remap` carries into every command still on the stacks. */
export type Edit =
  | { kind: "create"; id: number; data: SegmentData }
  | { kind: "update"; id: number; before: SegmentData; after: SegmentData }
  | { kind: "delete"; id: number; data: SegmentData };

/** The edit that reverses `edit`. */
export function inverse(edit: Edit): Edit {
  switch (edit.kind) {
    case "create":
      return { kind: "delete", id: edit.id, data: edit.data };
    case "delete":
      return { kind: "create", id: edit.id, data: edit.data };
    case "update":
      return { kind: "update", id: edit.id, before: edit.after, after: edit.before };
  }
}

export class UndoStack {
  private done: Edit[] = [];
  private undone: Edit[] = [];

  constructor(private readonly limit = 200) {}

  get canUndo(): boolean {
    return this.done.length > 0;
  }

  get canRedo(): boolean {
    return this.undone.length > 0;
  }

  /** A new edit by the user: it clears the redo stack. */
  push(edit: Edit): void {
    this.done.push(edit);
    if (this.done.length > this.limit) this.done.shift();
    this.undone = [];
  }

  /** The edit to apply to undo the last one (already moved to the redo stack), or null. */
  undo(): Edit | null {
    const edit = this.done.pop();
    if (!edit) return null;
    this.undone.push(edit);
    return inverse(edit);
  }

  /** The edit to apply again, or null. */
  redo(): Edit | null {
    const edit = this.undone.pop();
    if (!edit) return null;
    this.done.push(edit);
    return edit;
  }

  /** A segment was re-created under a new id: update every remembered edit. */
  remap(oldId: number, newId: number): void {
    for (const list of [this.done, this.undone])
      for (let i = 0; i < list.length; i += 1)
        if (list[i].id === oldId) list[i] = { ...list[i], id: newId };
  }

  /** Take back the last undo/redo bookkeeping when the server refused the edit. */
  rollback(wasUndo: boolean): void {
    if (wasUndo) {
      const edit = this.undone.pop();
      if (edit) this.done.push(edit);
    } else {
      const edit = this.done.pop();
      if (edit) this.undone.push(edit);
    }
  }
}

// -- labels ---------------------------------------------------------------------------------

export interface LabelChoice {
  key: string;
  name: string;
}

/** Number keys 1..9 label with these, in this order (fall stages first, then look-alikes). */
export const QUICK_LABELS: Record<string, string[]> = {
  walking: [
    "walking", "standing", "stumbling", "falling", "impact", "lying_on_floor",
    "trying_to_get_up", "sitting_down", "bending",
  ],
  wheelchair: [
    "sitting_wheelchair", "slumped_unconscious_wheelchair", "falling_out_of_wheelchair",
    "lying_on_floor", "standing_up_from_wheelchair", "crushing_hazard", "too_far_away",
    "gesturing", "bending",
  ],
  combined: [
    "walking", "sitting_wheelchair", "stumbling", "falling", "impact", "lying_on_floor",
    "standing_up_from_wheelchair", "crushing_hazard", "too_far_away",
  ],
};

/** Labels matching a search text (key or name, case-insensitive), prefix matches first. */
export function searchLabels<T extends LabelChoice>(labels: readonly T[], text: string): T[] {
  const q = text.trim().toLowerCase();
  if (!q) return [...labels];
  const hits = labels.filter(
    (l) => l.key.toLowerCase().includes(q) || l.name.toLowerCase().includes(q),
  );
  const starts = (l: T) =>
    l.key.toLowerCase().startsWith(q) || l.name.toLowerCase().startsWith(q) ? 0 : 1;
  return hits.sort((a, b) => starts(a) - starts(b));
}

/** The segment under the playhead, preferring the shortest (most specific) one. */
export function segmentAt<T extends Span>(segments: readonly T[], frame: number): T | null {
  let best: T | null = null;
  for (const s of segments)
    if (s.first_frame <= frame && frame <= s.last_frame)
      if (!best || s.last_frame - s.first_frame < best.last_frame - best.first_frame) best = s;
  return best;
}

/** The label Enter applies from the search box: the one the user moved to with the arrow keys,
 * or the only match. Never a guess among several matches. */
export function searchChoice<T>(matches: readonly T[], active: number | null): T | null {
  if (active !== null && active >= 0 && active < matches.length) return matches[active];
  return matches.length === 1 ? matches[0] : null;
}

/** The highlighted match after an arrow key, clamped to the list (null: nothing highlighted). */
export function moveActive(active: number | null, delta: 1 | -1, count: number): number | null {
  if (count === 0) return null;
  if (active === null) return delta > 0 ? 0 : count - 1;
  return Math.min(Math.max(active + delta, 0), count - 1);
}

/** Sub-row of every segment in a lane so that overlapping segments never share one and so never
 * hide each other: greedy interval partitioning by first frame (longer first on ties). */
export function packSubRows<T extends Span & { id: number }>(
  segments: readonly T[],
): { subRow: Map<number, number>; count: number } {
  const order = [...segments].sort(
    (a, b) =>
      a.first_frame - b.first_frame ||
      b.last_frame - b.first_frame - (a.last_frame - a.first_frame) ||
      a.id - b.id,
  );
  const ends: number[] = [];
  const subRow = new Map<number, number>();
  for (const s of order) {
    let row = ends.findIndex((end) => end < s.first_frame);
    if (row === -1) {
      row = ends.length;
      ends.push(s.last_frame);
    } else ends[row] = s.last_frame;
    subRow.set(s.id, row);
  }
  return { subRow, count: Math.max(ends.length, 1) };
}

export { labelColours } from "../../lib/labelColours";
