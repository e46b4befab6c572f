import { useEffect, useMemo, useRef } from "react";
import { drawSkeleton, type Transform } from "./skeletonDrawing";
import type { LabellingVideo, SkeletonFrame } from "./types";

interface Props {
  video: LabellingVideo;
  frames: (SkeletonFrame | undefined)[];
  frame: number;
  showRgb: boolean;
  blur: boolean;
  width?: number;
}

export function rgbUrl(videoId: number, frame: number, blur: boolean): string {
  return `/api/labelling/videos/${videoId}/rgb/${frame}${blur ? "" : "?blur=false"}`;
}

/** Keypoints in pixels of the video's image, or normalised: fit the whole clip once. */
function transformFor(video: LabellingVideo, frames: (SkeletonFrame | undefined)[], w: number, h: number): Transform {
  if (video.image_width && video.image_height)
    return { scaleX: w / video.image_width, scaleY: h / video.image_height, offsetX: 0, offsetY: 0 };
  let minX = Infinity, minY = Infinity, maxX = -Infinity, maxY = -Infinity;
  for (const f of frames)
    for (const [x, y, c] of f?.keypoints ?? [])
      if (c > 0) {
        minX = Math.min(minX, x); maxX = Math.max(maxX, x);
        minY = Math.min(minY, y); maxY = Math.max(maxY, y);
      }
  if (!Number.isFinite(minX)) return { scaleX: 1, scaleY: 1, offsetX: 0, offsetY: 0 };
  const scale = 0.9 * Math.min(w / Math.max(maxX - minX, 1e-6), h / Math.max(maxY - minY, 1e-6));
  return {
    scaleX: scale, scaleY: scale,
    offsetX: (w - (maxX - minX) * scale) / 2 - minX * scale,
    offsetY: (h - (maxY - minY) * scale) / 2 - minY * scale,
  };
}

/** The exact frame: the RGB picture from the server (head blurred unless turned off) under
 * the skeleton drawn with depth as colour and confidence as opacity. */
export function Player({ video, frames, frame, showRgb, blur, width = 640 }: Props) {
  const aspect = video.image_width && video.image_height ? video.image_height / video.image_width : 0.75;
  const height = Math.round(width * aspect);
  const canvas = useRef<HTMLCanvasElement>(null);
  const transform = useMemo(() => transformFor(video, frames, width, height), [video, frames, width, height]);
  const current = frames[frame];

  useEffect(() => {
    const ctx = canvas.current?.getContext("2d");
    if (!ctx) return;
    ctx.clearRect(0, 0, width, height);
    if (current) drawSkeleton(ctx, current.keypoints, current.depth, transform);
  }, [current, transform, width, height]);

  useEffect(() => {
    // Warm the server's frame cache and the browser's for the next frames.
    if (!showRgb || !video.has_rgb) return;
    for (let k = 1; k <= 3; k += 1)
      if (frame + k < video.frame_count) new Image().src = rgbUrl(video.id, frame + k, blur);
  }, [frame, showRgb, blur, video]);

  return (
    <div className="player" style={{ width, height }} data-testid="player">
      {showRgb && video.has_rgb ? (
        <img src={rgbUrl(video.id, frame, blur)} width={width} height={height} alt={`RGB frame ${frame}`} />
      ) : (
        <div className="player-dark" />
      )}
      <canvas ref={canvas} width={width} height={height} aria-label="Skeleton" />
      {!current && <span className="player-note">no pose in this frame</span>}
    </div>
  );
}
