import { useEffect, useRef, useState, type PointerEvent } from "react";
import { classColour, type Segment } from "./types";
import { dragEdge, frameToX, packSubRows, xToFrame, type Span } from "./timelineLogic";

export interface TimelineRow {
  title: string;
  segments: Segment[];
  editable: boolean;
  isEditable: (segment: Segment) => boolean;
}

interface Props {
  frameCount: number;
  fps: number;
  frame: number;
  rows: TimelineRow[];
  selectedId: number | null;
  inPoint: number | null;
  outPoint: number | null;
  probability: (number | null)[] | null;
  threshold: number | null;
  suggestions: Span[];
  laneNote: string;
  laneError: string | null;
  onSeek: (frame: number) => void;
  onSelect: (id: number | null) => void;
  onResize: (id: number, span: Span) => void;
  onAcceptSuggestion: (span: Span) => void;
  /** The fill of a segment: every fine label has its own colour. */
  labelColour: (labelKey: string) => string;
}

const ROW = 30;
const RULER = 22;
const LANE = 64;
const TITLE = 150;

interface Drag {
  id: number;
  edge: "first" | "last";
  span: Span;
}

/** Segments per annotator (filled in their fine label's colour with a stripe of their class's
 * colour; overlapping segments go to sub-rows of the lane so none hides another), the model
 * lane, the playhead, in/out marks. Click to seek, drag a segment edge to move it. */
export function Timeline(props: Props) {
  const { frameCount, fps, frame, rows, probability, threshold } = props;
  const box = useRef<HTMLDivElement>(null);
  const [width, setWidth] = useState(800);
  const [drag, setDrag] = useState<Drag | null>(null);

  useEffect(() => {
    const measure = () => setWidth(Math.max((box.current?.clientWidth ?? 920) - TITLE, 200));
    measure();
    window.addEventListener("resize", measure);
    return () => window.removeEventListener("resize", measure);
  }, []);

  const x = (f: number) => TITLE + frameToX(f, frameCount, width);
  const frameAt = (event: PointerEvent<SVGElement>) => {
    const rect = (event.currentTarget.ownerSVGElement ?? event.currentTarget).getBoundingClientRect();
    return xToFrame(event.clientX - rect.left - TITLE, frameCount, width);
  };
  const lanesTop = RULER;
  const lanes = rows.map((row) => packSubRows(row.segments));
  const laneTops = lanes.reduce<number[]>((tops, lane, r) => [...tops, tops[r] + lane.count * ROW], [lanesTop]);
  const modelTop = laneTops[rows.length] + 6;
  const height = modelTop + LANE + 4;
  const seconds = Math.floor(frameCount / fps);
  const tickEvery = seconds > 40 ? 10 : seconds > 15 ? 5 : 1;

  const startDrag = (event: PointerEvent<SVGRectElement>, segment: Segment, edge: "first" | "last") => {
    event.stopPropagation();
    event.currentTarget.setPointerCapture(event.pointerId);
    props.onSelect(segment.id);
    setDrag({ id: segment.id, edge, span: { first_frame: segment.first_frame, last_frame: segment.last_frame } });
  };
  const moveDrag = (event: PointerEvent<SVGRectElement>) => {
    if (!drag) return;
    setDrag({ ...drag, span: dragEdge(drag.span, drag.edge, frameAt(event), frameCount) });
  };
  const endDrag = () => {
    if (!drag) return;
    props.onResize(drag.id, drag.span);
    setDrag(null);
  };

  const probabilityPath = (() => {
    if (!probability) return "";
    let path = "";
    let pen = false;
    probability.forEach((p, i) => {
      if (p === null) {
        pen = false;
        return;
      }
      const px = x(i + 0.5);
      const py = modelTop + LANE - p * (LANE - 4);
      path += `${pen ? "L" : "M"}${px.toFixed(1)},${py.toFixed(1)} `;
      pen = true;
    });
    return path;
  })();

  return (
    <div className="timeline" ref={box} data-testid="timeline">
      <svg
        width={TITLE + width}
        height={height}
        role="group"
        aria-label="Timeline"
        onPointerDown={(event) => {
          if ((event.target as Element).getAttribute("data-role") === "edge") return;
          props.onSeek(frameAt(event));
        }}
      >
        <rect x={TITLE} y={0} width={width} height={height} fill="#f8fafc" />
        {Array.from({ length: seconds + 1 }, (_, s) => s)
          .filter((s) => s % tickEvery === 0)
          .map((s) => (
            <g key={s}>
              <line x1={x(s * fps)} x2={x(s * fps)} y1={RULER - 6} y2={height} stroke="#e2e8f0" />
              <text x={x(s * fps) + 2} y={12} fontSize={11} fill="#64748b">{s}s</text>
            </g>
          ))}
        {rows.map((row, r) => {
          const laneTop = laneTops[r];
          const laneBottom = laneTops[r + 1];
          return (
            <g key={row.title} data-row={row.title} data-sub-rows={lanes[r].count}>
              <text x={4} y={laneTop + 19} fontSize={12} fill="#334155">{row.title}</text>
              <line x1={TITLE} x2={TITLE + width} y1={laneBottom} y2={laneBottom} stroke="#e2e8f0" />
              {row.segments.map((segment) => {
                const subRow = lanes[r].subRow.get(segment.id) ?? 0;
                const top = laneTop + subRow * ROW;
                const span = drag?.id === segment.id ? drag.span : segment;
                const left = x(span.first_frame);
                const right = x(span.last_frame + 1);
                const selected = props.selectedId === segment.id;
                const dashed = segment.status === "draft" || segment.status === "pending";
                return (
                  <g
                    key={segment.id}
                    data-testid="segment"
                    data-segment-id={segment.id}
                    data-first={span.first_frame}
                    data-last={span.last_frame}
                    data-label={segment.label_key}
                    data-status={segment.status}
                    data-sub-row={subRow}
                    onPointerDown={(event) => {
                      event.stopPropagation();
                      props.onSelect(segment.id);
                      props.onSeek(frameAt(event));
                    }}
                  >
                    <rect
                      x={left}
                      y={top + 3}
                      width={Math.max(right - left, 2)}
                      height={ROW - 6}
                      rx={4}
                      fill={props.labelColour(segment.label_key)}
                      fillOpacity={segment.status === "rejected" ? 0.25 : 0.85}
                      stroke={selected ? "#0f172a" : "#ffffff"}
                      strokeWidth={selected ? 2.5 : 1}
                      strokeDasharray={dashed ? "4 3" : undefined}
                    >
                      <title>
                        {`${segment.label_name ?? segment.label_key} · frames ${span.first_frame}–${span.last_frame} · ${segment.status}`}
                      </title>
                    </rect>
                    <rect
                      x={left + 1}
                      y={top + ROW - 8}
                      width={Math.max(right - left - 2, 1)}
                      height={4}
                      fill={classColour(segment.decision)}
                      pointerEvents="none"
                    />
                    <text x={left + 4} y={top + 19} fontSize={11} fill="#fff" pointerEvents="none">
                      {right - left > 40 ? (segment.label_name ?? segment.label_key) : ""}
                    </text>
                    {row.isEditable(segment) &&
                      (["first", "last"] as const).map((edge) => (
                        <rect
                          key={edge}
                          data-role="edge"
                          data-edge={edge}
                          x={(edge === "first" ? left : right) - 4}
                          y={top + 3}
                          width={8}
                          height={ROW - 6}
                          fill="#0f172a"
                          fillOpacity={selected ? 0.5 : 0.15}
                          style={{ cursor: "ew-resize" }}
                          onPointerDown={(event) => startDrag(event, segment, edge)}
                          onPointerMove={moveDrag}
                          onPointerUp={endDrag}
                        />
                      ))}
                  </g>
                );
              })}
            </g>
          );
        })}
        <g data-testid="model-lane">
          <text x={4} y={modelTop + 16} fontSize={12} fill="#334155">Model P(emergency)</text>
          <text x={4} y={modelTop + 32} fontSize={10} fill={props.laneError ? "#b91c1c" : "#64748b"}>
            {props.laneNote}
            {props.laneError && <title>{props.laneError}</title>}
          </text>
          <rect x={TITLE} y={modelTop} width={width} height={LANE} fill="#fff" stroke="#e2e8f0" />
          {props.suggestions.map((s) => (
            <g key={`${s.first_frame}-${s.last_frame}`} data-testid="suggestion">
              <rect
                x={x(s.first_frame)}
                y={modelTop}
                width={x(s.last_frame + 1) - x(s.first_frame)}
                height={LANE}
                fill="#dc2626"
                fillOpacity={0.12}
              />
              <text
                x={x(s.first_frame) + 3}
                y={modelTop + 12}
                fontSize={11}
                fill="#991b1b"
                style={{ cursor: "pointer", textDecoration: "underline" }}
                onPointerDown={(event) => {
                  event.stopPropagation();
                  props.onAcceptSuggestion(s);
                }}
              >
                accept {s.first_frame}–{s.last_frame}
              </text>
            </g>
          ))}
          {threshold !== null && probability && (
            <line
              x1={TITLE}
              x2={TITLE + width}
              y1={modelTop + LANE - threshold * (LANE - 4)}
              y2={modelTop + LANE - threshold * (LANE - 4)}
              stroke="#991b1b"
              strokeDasharray="3 3"
            />
          )}
          <path d={probabilityPath} fill="none" stroke="#b91c1c" strokeWidth={1.5} />
        </g>
        {[props.inPoint, props.outPoint].map((mark, k) =>
          mark === null ? null : (
            <g key={k} data-testid={k === 0 ? "in-mark" : "out-mark"}>
              <line x1={x(mark + k)} x2={x(mark + k)} y1={RULER - 4} y2={height} stroke="#2563eb" strokeWidth={2} />
              <text x={x(mark + k) + (k ? -12 : 2)} y={RULER - 8} fontSize={11} fill="#2563eb">{k ? "out" : "in"}</text>
            </g>
          ),
        )}
        {props.inPoint !== null && props.outPoint !== null && (
          <rect
            x={x(Math.min(props.inPoint, props.outPoint))}
            y={RULER}
            width={x(Math.max(props.inPoint, props.outPoint) + 1) - x(Math.min(props.inPoint, props.outPoint))}
            height={height - RULER}
            fill="#2563eb"
            fillOpacity={0.08}
            pointerEvents="none"
          />
        )}
        <line x1={x(frame + 0.5)} x2={x(frame + 0.5)} y1={0} y2={height} stroke="#0f172a" strokeWidth={1.5} pointerEvents="none" />
      </svg>
    </div>
  );
}
