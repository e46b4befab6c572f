import type { FilterStep, ReplayFrame } from "../lib/replay";

interface Props {
  frames: readonly ReplayFrame[];
  steps: readonly FilterStep[];
  threshold: number | null;
  /** The alarm's frame span [first ts, last ts]; time 0 on the axis is its start. */
  span: readonly [number, number] | null;
  index: number;
  onSelect(index: number): void;
}

const W = 640;
const H = 200;
const PAD = { left: 36, right: 8, top: 10, bottom: 34 };
const FILTER_COLOR = { idle: "#cbd5e1", counting: "#f59e0b", fired: "#dc2626" } as const;

/** Per-frame Emergency probability, the threshold line, and the delay filter's state as a strip. */
export function ProbabilityChart({ frames, steps, threshold, span, index, onSelect }: Props) {
  if (frames.length === 0) return <p className="empty">No frames stored around this alarm.</p>;
  const t0 = frames[0].ts;
  const t1 = Math.max(frames[frames.length - 1].ts, t0 + 1e-3);
  const pw = W - PAD.left - PAD.right;
  const ph = H - PAD.top - PAD.bottom - 14;
  const x = (ts: number) => PAD.left + ((ts - t0) / (t1 - t0)) * pw;
  const y = (p: number) => PAD.top + (1 - p) * ph;
  const points = steps
    .map((s, i) => (s.emergencyScore === null ? null : `${x(frames[i].ts).toFixed(1)},${y(s.emergencyScore).toFixed(1)}`))
    .filter(Boolean)
    .join(" ");
  const strip = PAD.top + ph + 4;
  const alarmTs = span ? span[0] : null;

  function pick(event: React.MouseEvent<SVGSVGElement>) {
    const box = event.currentTarget.getBoundingClientRect();
    const ts = t0 + (((event.clientX - box.left) * (W / box.width) - PAD.left) / pw) * (t1 - t0);
    let best = 0;
    frames.forEach((f, i) => {
      if (Math.abs(f.ts - ts) < Math.abs(frames[best].ts - ts)) best = i;
    });
    onSelect(best);
  }

  return (
    <svg viewBox={`0 0 ${W} ${H}`} className="chart prob-chart" onClick={pick} role="img"
      aria-label="How sure the robot was of an emergency, per frame">
      {[0, 0.5, 1].map((p) => (
        <g key={p}>
          <line x1={PAD.left} x2={W - PAD.right} y1={y(p)} y2={y(p)} className="grid" />
          <text x={PAD.left - 4} y={y(p) + 4} textAnchor="end" className="tick">{`${p * 100}%`}</text>
        </g>
      ))}
      {steps.map((s, i) => {
        const next = frames[i + 1]?.ts ?? t1;
        return <rect key={i} x={x(frames[i].ts)} width={Math.max(0.5, x(next) - x(frames[i].ts))}
          y={strip} height={10} fill={FILTER_COLOR[s.state]} />;
      })}
      <text x={PAD.left - 4} y={strip + 9} textAnchor="end" className="tick">alarm</text>
      <polyline points={points} className="prob-line" />
      {threshold !== null && (
        <g>
          <line x1={PAD.left} x2={W - PAD.right} y1={y(threshold)} y2={y(threshold)} className="threshold" />
          <text x={W - PAD.right} y={y(threshold) - 4} textAnchor="end" className="threshold-label">
            alarm level {Math.round(threshold * 100)}%
          </text>
        </g>
      )}
      {span && (
        <rect x={x(span[0])} width={Math.max(1, x(span[1]) - x(span[0]))} y={PAD.top} height={ph}
          className="alarm-span"><title>frames of the alarm</title></rect>
      )}
      <line x1={x(frames[index]?.ts ?? t0)} x2={x(frames[index]?.ts ?? t0)} y1={PAD.top}
        y2={strip + 10} className="cursor" />
      <text x={PAD.left} y={H - 4} className="tick">{`${(t0 - (alarmTs ?? t0)).toFixed(1)} s`}</text>
      <text x={W - PAD.right} y={H - 4} textAnchor="end" className="tick">
        {`+${(t1 - (alarmTs ?? t0)).toFixed(1)} s`}
      </text>
    </svg>
  );
}
