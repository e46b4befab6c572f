import { bars, niceMax, ticks } from "../lib/charts";

interface Props {
  title: string;
  data: ReadonlyArray<{ key: string; label: string; value: number }>;
  format?: (v: number) => string;
  max?: number;
  color?: string;
}

const W = 560;
const H = 220;
const PAD = { left: 44, right: 8, top: 12, bottom: 52 };

/** A plain SVG bar chart. */
export function BarChart({ title, data, format = String, max, color = "#2563eb" }: Props) {
  const pw = W - PAD.left - PAD.right;
  const ph = H - PAD.top - PAD.bottom;
  const top = max ?? niceMax(Math.max(0, ...data.map((d) => d.value)));
  const rects = bars(data, pw, ph, top);
  return (
    <figure className="chart-figure">
      <figcaption>{title}</figcaption>
      {data.length === 0 ? (
        <p className="empty">No data in this period.</p>
      ) : (
        <svg viewBox={`0 0 ${W} ${H}`} className="chart" role="img" aria-label={title}>
          {ticks(top).map((t) => (
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
              <text x={r.x + r.width / 2} y={ph + 12} textAnchor="end" className="tick"
                transform={`rotate(-35 ${r.x + r.width / 2} ${ph + 12})`}>{data[i].label}</text>
            </g>
          ))}
        </svg>
      )}
    </figure>
  );
}
