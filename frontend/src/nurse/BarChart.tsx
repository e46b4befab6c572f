import { bars, niceMax, ticks } from "../lib/charts";

interface Props {
  title: string;
  data: ReadonlyArray<{ key: string; label: string; value: number }>;
  format?: (v: number) => string;
  max?: number;
  color?: string;
  /** Counts: only whole-number ticks. */
  integer?: boolean;
}

const W = 560;
const H = 220;
const PAD = { left: 44, right: 8, top: 12, bottom: 52 };
const MAX_BAR = 64;

/** A plain SVG bar chart. */
export function BarChart({ title, data, format = String, max, color = "#2563eb", integer = false }: Props) {
  const pw = W - PAD.left - PAD.right;
  const ph = H - PAD.top - PAD.bottom;
  const top = max ?? niceMax(Math.max(0, ...data.map((d) => d.value)));
  const rects = bars(data, pw, ph, top).map((r) => {
    const width = Math.min(r.width, MAX_BAR);
    return { ...r, x: r.x + (r.width - width) / 2, width };
  });
  const tickValues = integer && top < 4 ? ticks(top, Math.max(1, top)) : ticks(top);
  const rotate = data.length > 6;
  return (
    <figure className="chart-figure">
      <figcaption>{title}</figcaption>
      {data.length === 0 ? (
        <p className="empty">No data in this period.</p>
      ) : (
        <svg viewBox={`0 0 ${W} ${H}`} className="chart" role="img" aria-label={title}>
          {tickValues.map((t) => (
            <g key={t}>
              <line x1={PAD.left} x2={W - PAD.right} y1={PAD.top + ph - (t / top) * ph}
                y2={PAD.top + ph - (t / top) * ph} className="grid" />
              <text x={PAD.left - 4} y={PAD.top + ph - (t / top) * ph + 4} textAnchor="end" className="tick">
                {format(t)}
              </text>
            </g>
          ))}
          {rects.map((r, i) => (
            <g key={r.key} transform={`translate(${PAD.left},${PAD.top})`}>
              <rect x={r.x} y={r.y} width={r.width} height={r.height} fill={color}>
                <title>{`${data[i].label}: ${format(r.value)}`}</title>
              </rect>
              <text x={r.x + r.width / 2} y={ph + 14} textAnchor={rotate ? "end" : "middle"}
                className="tick"
                transform={rotate ? `rotate(-35 ${r.x + r.width / 2} ${ph + 14})` : undefined}>
                {data[i].label}
              </text>
            </g>
          ))}
        </svg>
      )}
    </figure>
  );
}
