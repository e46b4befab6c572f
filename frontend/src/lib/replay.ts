// Alarm replay logic: the delay filter's state per frame and skeleton drawing geometry.

export interface ReplayFrame {
  seq: number | null;
  ts: number;
  keypoints: number[][];
  decision: string | null;
  scores: Record<string, number>;
}

export type FilterState = "idle" | "counting" | "fired";

export interface FilterStep {
  emergencyScore: number | null;
  rawEmergency: boolean;
  heldMs: number;
  state: FilterState;
}

/**
 * Re-run the delay filter over the frames: the raw per-frame decision is Emergency when its score
 * passes the threshold (or, without scores, when the frame's decision says so); an alarm fires once
 * Emergency has held for delay_ms without interruption.
 */
export function delayFilter(
  frames: readonly ReplayFrame[],
  threshold: number | null,
  delayMs: number | null,
): FilterStep[] {
  let runStart: number | null = null;
  return frames.map((frame) => {
    const score = frame.scores?.emergency ?? null;
    const raw =
      score !== null && threshold !== null ? score >= threshold : frame.decision === "emergency";
    if (!raw) {
      runStart = null;
      return { emergencyScore: score, rawEmergency: false, heldMs: 0, state: "idle" };
    }
    runStart ??= frame.ts;
    const heldMs = Math.round((frame.ts - runStart) * 1000);
    const state: FilterState = heldMs >= (delayMs ?? 0) ? "fired" : "counting";
    return { emergencyScore: score, rawEmergency: true, heldMs, state };
  });
}

/** OpenPose BODY_25 bones (same as vigil.skeleton.BONES). */
export const BONES: ReadonlyArray<readonly [number, number]> = [
  [1, 0], [0, 15], [15, 17], [0, 16], [16, 18],
  [1, 2], [2, 3], [3, 4], [1, 5], [5, 6], [6, 7],
  [1, 8], [8, 9], [9, 10], [10, 11], [11, 24], [11, 22], [22, 23],
  [8, 12], [12, 13], [13, 14], [14, 21], [14, 19], [19, 20],
];

export interface Fit {
  scale: number;
  offsetX: number;
  offsetY: number;
}

/** One transform for all frames (so the person moves, not the camera), keeping aspect ratio. */
export function fitSkeletons(
  frames: readonly ReplayFrame[],
  width: number,
  height: number,
  margin = 12,
): Fit {
  let minX = Infinity;
  let minY = Infinity;
  let maxX = -Infinity;
  let maxY = -Infinity;
  for (const f of frames) {
    for (const [x, y, c] of f.keypoints) {
      if (!(c > 0)) continue;
      minX = Math.min(minX, x);
      maxX = Math.max(maxX, x);
      minY = Math.min(minY, y);
      maxY = Math.max(maxY, y);
    }
  }
  if (!Number.isFinite(minX)) return { scale: 1, offsetX: 0, offsetY: 0 };
  const spanX = Math.max(maxX - minX, 1e-6);
  const spanY = Math.max(maxY - minY, 1e-6);
  const scale = Math.min((width - 2 * margin) / spanX, (height - 2 * margin) / spanY);
  return {
    scale,
    offsetX: margin + (width - 2 * margin - spanX * scale) / 2 - minX * scale,
    offsetY: margin + (height - 2 * margin - spanY * scale) / 2 - minY * scale,
  };
}

/** Index of the frame nearest to a time (frames sorted by ts). */
export function frameAt(frames: readonly ReplayFrame[], ts: number): number {
  let lo = 0;
  let hi = frames.length - 1;
  if (hi < 0) return -1;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (frames[mid].ts < ts) lo = mid + 1;
    else hi = mid;
  }
  if (lo > 0 && Math.abs(frames[lo - 1].ts - ts) <= Math.abs(frames[lo].ts - ts)) return lo - 1;
  return lo;
}
