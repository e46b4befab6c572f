// Drawing a BODY_25 skeleton: depth as colour, joint confidence as opacity.
import { BONES } from "../../lib/replay";

export const DEPTH_NEAR_M = 1.0;
export const DEPTH_FAR_M = 5.0;

/** Near = warm (red), far = cool (blue); unknown depth = light grey. */
export function depthColour(depth: number | null | undefined): string {
  if (depth === null || depth === undefined || !Number.isFinite(depth)) return "#e2e8f0";
  const t = Math.min(Math.max((depth - DEPTH_NEAR_M) / (DEPTH_FAR_M - DEPTH_NEAR_M), 0), 1);
  const hue = Math.round(t * 230); // 0 red .. 230 blue
  return `hsl(${hue} 90% 55%)`;
}

export interface Transform {
  scaleX: number;
  scaleY: number;
  offsetX: number;
  offsetY: number;
}

export function drawSkeleton(
  ctx: CanvasRenderingContext2D,
  keypoints: number[][],
  depth: (number | null)[] | null | undefined,
  t: Transform,
): void {
  const x = (i: number) => keypoints[i][0] * t.scaleX + t.offsetX;
  const y = (i: number) => keypoints[i][1] * t.scaleY + t.offsetY;
  const conf = (i: number) => Math.min(Math.max(keypoints[i]?.[2] ?? 0, 0), 1);
  const d = (i: number) => depth?.[i] ?? null;
  ctx.lineWidth = 4;
  ctx.lineCap = "round";
  for (const [a, b] of BONES) {
    if (conf(a) <= 0 || conf(b) <= 0) continue;
    ctx.globalAlpha = Math.min(conf(a), conf(b));
    const da = d(a);
    const db = d(b);
    ctx.strokeStyle = depthColour(da !== null && db !== null ? (da + db) / 2 : (da ?? db));
    ctx.beginPath();
    ctx.moveTo(x(a), y(a));
    ctx.lineTo(x(b), y(b));
    ctx.stroke();
  }
  keypoints.forEach((_, i) => {
    if (conf(i) <= 0) return;
    ctx.globalAlpha = conf(i);
    ctx.fillStyle = depthColour(d(i));
    ctx.beginPath();
    ctx.arc(x(i), y(i), 4.5, 0, 2 * Math.PI);
    ctx.fill();
    ctx.strokeStyle = "#0f172a";
    ctx.lineWidth = 1;
    ctx.stroke();
    ctx.lineWidth = 4;
  });
  ctx.globalAlpha = 1;
}
