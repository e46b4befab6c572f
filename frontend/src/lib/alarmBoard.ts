// The live alarm board's state: every open or acknowledged alarm, kept from websocket messages.
import type { Alarm, BrowserMessage } from "../api/types";

export type Board = ReadonlyMap<number, Alarm>;

export const emptyBoard: Board = new Map();

/** A snapshot replaces the board (after every (re)connect); an alarm message updates one entry.
 *
 * Fail open: while storage is stalled the server pushes alarms marked `stored: false` (with a
 * provisional negative id). The stored alarm with the same `key` replaces such a card once
 * storage recovers, and a not-yet-stored alarm is not shown beside a stored live one of its key:
 * one card per alarm, never two. */
export function applyMessage(board: Board, message: BrowserMessage): Board {
  if (message.type === "snapshot") {
    let next: Board = emptyBoard;
    for (const a of message.alarms.filter((x) => isStored(x))) next = applyMessage(next, { type: "alarm", alarm: a });
    for (const a of message.alarms.filter((x) => !isStored(x))) next = applyMessage(next, { type: "alarm", alarm: a });
    return next;
  }
  const alarm = message.alarm;
  const known = board.get(alarm.id);
  // Messages may overtake each other; never let an older version replace a newer one.
  if (known && Date.parse(known.updated_at) > Date.parse(alarm.updated_at)) return board;
  if (!isStored(alarm) && isLive(alarm)) {
    for (const other of board.values()) {
      if (isStored(other) && other.key === alarm.key && isLive(other)) return board; // already shown
    }
  }
  const next = new Map(board);
  if (isStored(alarm)) {
    for (const [id, other] of board) if (!isStored(other) && other.key === alarm.key) next.delete(id);
  }
  if (isLive(alarm)) next.set(alarm.id, alarm);
  else next.delete(alarm.id);
  return next;
}

/** False while the alarm was pushed before storage could keep it (fail open). */
export function isStored(alarm: Alarm): boolean {
  return alarm.stored !== false;
}

export function isLive(alarm: Alarm): boolean {
  return alarm.state === "open" || alarm.state === "acknowledged";
}

const PRIORITY_RANK: Record<Alarm["priority"], number> = { high: 0, medium: 1, technical: 2 };

/** Re-alarmed: acknowledged, then not resolved in time, so it calls for attention again. */
export function isRealarmed(alarm: Alarm): boolean {
  return (
    alarm.state === "acknowledged" &&
    !!alarm.realarmed_at &&
    (!alarm.acknowledged_at || Date.parse(alarm.realarmed_at) >= Date.parse(alarm.acknowledged_at))
  );
}

/** Open or re-alarmed: the alarm wants a nurse now. */
export function needsAttention(alarm: Alarm): boolean {
  return alarm.state === "open" || isRealarmed(alarm);
}

/** Needing attention first, then by priority, then oldest first (it has waited longest). */
export function sortForBoard(alarms: Iterable<Alarm>): Alarm[] {
  return [...alarms].sort(
    (a, b) =>
      Number(!needsAttention(a)) - Number(!needsAttention(b)) ||
      PRIORITY_RANK[a.priority] - PRIORITY_RANK[b.priority] ||
      Date.parse(a.raised_at) - Date.parse(b.raised_at) ||
      a.id - b.id,
  );
}

export function inWard(alarms: Iterable<Alarm>, ward: string | null): Alarm[] {
  return [...alarms].filter((a) => ward === null || a.ward === ward);
}

export function wardsOf(alarms: Iterable<Alarm>): string[] {
  const wards = new Set<string>();
  for (const a of alarms) if (a.ward) wards.add(a.ward);
  return [...wards].sort();
}

/** The emergency sound repeats while any emergency on the shown board is unacknowledged (or
 * re-alarmed because it was acknowledged but not resolved in time). */
export function soundRequired(alarms: Iterable<Alarm>): boolean {
  for (const a of alarms) if (a.kind === "emergency" && needsAttention(a)) return true;
  return false;
}

export type AlarmStyle = "emergency" | "pause" | "technical";

export function styleOf(alarm: Alarm): AlarmStyle {
  if (alarm.kind === "emergency") return "emergency";
  if (alarm.kind === "pause") return "pause";
  return "technical";
}

export const KIND_LABEL: Record<Alarm["kind"], string> = {
  emergency: "Emergency",
  pause: "Pause",
  robot_offline: "Robot offline",
  stream_stalled: "Stream stalled",
  detection_degraded: "Detection degraded",
  storage_stalled: "Storage stalled",
};

const INPUT_WORDS: Record<string, string> = { keypoints: "keypoints", depth: "depth", floor: "floor measures" };

/** What a technical alarm is about, in a line: "Detection degraded: no depth/floor measures,
 * running keypoints-only fallback gbt-kp-3" (from the alarm's details). */
export function alarmTitle(alarm: Alarm): string {
  const label = KIND_LABEL[alarm.kind];
  if (alarm.kind !== "detection_degraded") return label;
  const details = (alarm.details ?? {}) as Record<string, unknown>;
  const missing = Array.isArray(details.missing_inputs) ? (details.missing_inputs as string[]) : [];
  const running = typeof details.running_model === "string" ? details.running_model : null;
  const assigned = typeof details.assigned_model === "string" ? details.assigned_model : null;
  // Degraded with no input missing: the robot refused its model (its file is not the registry's).
  const what = missing.length ? `no ${missing.map((m) => INPUT_WORDS[m] ?? m).join("/")}`
    : assigned ? `model ${assigned} refused` : "an input is missing";
  const how = running && running !== assigned ? `running keypoints-only fallback ${running}`
    : running ? `${running} runs on what is left` : "no fallback model";
  return `${label}: ${what}, ${how}`;
}
