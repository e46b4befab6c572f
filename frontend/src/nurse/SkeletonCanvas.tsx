import { useEffect, useMemo, useRef } from "react";
import { BONES, fitSkeletons, type ReplayFrame } from "../lib/replay";

interface Props {
  frames: readonly ReplayFrame[];
  index: number;
  color: string;
  width?: number;
  height?: number;
}

/** Draws frames[index]'s skeleton, with a faint trail of the previous frames. */
export function SkeletonCanvas({ frames, index, color, width = 360, height = 300 }: Props) {
  const ref = useRef<HTMLCanvasElement>(null);
  const fit = useMemo(() => fitSkeletons(frames, width, height), [frames, width, height]);

  useEffect(() => {
    const ctx = ref.current?.getContext("2d");
    if (!ctx) return;
    ctx.clearRect(0, 0, width, height);
    ctx.fillStyle = "#0f172a";
    ctx.fillRect(0, 0, width, height);
    const draw = (frame: ReplayFrame, alpha: number) => {
      const px = (i: number) => frame.keypoints[i][0] * fit.scale + fit.offsetX;
      const py = (i: number) => frame.keypoints[i][1] * fit.scale + fit.offsetY;
      const seen = (i: number) => (frame.keypoints[i]?.[2] ?? 0) > 0;
      ctx.globalAlpha = alpha;
      ctx.strokeStyle = color;
      ctx.lineWidth = 3;
      ctx.beginPath();
      for (const [a, b] of BONES) {
        if (!seen(a) || !seen(b)) continue;
        ctx.moveTo(px(a), py(a));
        ctx.lineTo(px(b), py(b));
      }
      ctx.stroke();
      ctx.fillStyle = "#f8fafc";
      frame.keypoints.forEach((_, i) => {
        if (seen(i)) ctx.fillRect(px(i) - 2, py(i) - 2, 4, 4);
      });
    };
    for (let k = 6; k >= 1; k -= 2) if (frames[index - k]) draw(frames[index - k], 0.12);
    if (frames[index]) draw(frames[index], 1);
    ctx.globalAlpha = 1;
  }, [frames, index, color, fit, width, height]);

  return <canvas ref={ref} width={width} height={height} className="skeleton" aria-label="Skeleton" />;
}
