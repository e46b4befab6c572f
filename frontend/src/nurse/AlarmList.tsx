import { memo, useLayoutEffect, useMemo, useRef, useState, type RefObject } from "react";
import { Link } from "react-router-dom";
import type { Alarm } from "../api/types";
import { alarmTitle, GROUP_LABEL, isRealarmed, isStored, mayAcknowledge, styleOf, transportEndedText, type TriageGroup } from "../lib/alarmBoard";
import { itemOffsets, visibleSlice } from "../lib/listWindow";
import { elapsed } from "../lib/time";
import { robotLabel } from "../lib/dispositions";

interface Props {
  groups: { group: TriageGroup; alarms: Alarm[] }[];
  now: number;
  busyId: number | null;
  onAcknowledge(alarm: Alarm): void;
  onResolve(alarm: Alarm): void;
}

/** What the state column says: "Missed: needs review", "Escalated ×3", "Acknowledged by ana"… */
export function stateText(alarm: Alarm): string {
  if (alarm.state === "missed") {
    return alarm.escalated_to ? `Missed: escalated to ${alarm.escalated_to}` : "Missed: needs review";
  }
  if (isRealarmed(alarm)) return "Re-alarm";
  if (alarm.state === "acknowledged") return `Acknowledged by ${alarm.acknowledged_by ?? "?"}`;
  if (alarm.escalation_level > 0) return `Escalated${alarm.escalation_level > 1 ? ` ×${alarm.escalation_level}` : ""}`;
  return "New";
}

/** Heights of the list's items (fixed in styles.css, so the list can place them unmeasured). */
export const ROW_PX = 52;
export const GROUP_HEAD_PX = 34;
/** Rows drawn beyond the window's edges, so a scroll shows rows already there. */
const OVERSCAN_PX = 800;

type Item = { group: TriageGroup; count: number; alarm?: undefined } | { group: TriageGroup; alarm: Alarm };

/** The compact board for many alarms: one row each, grouped in triage order. Only the rows in
 * (or near) the window are in the page: with hundreds of alarms, a new one re-renders a few dozen
 * rows, not all of them. */
export function AlarmList({ groups, now, busyId, onAcknowledge, onResolve }: Props) {
  const items = useMemo(
    () => groups.flatMap(({ group, alarms }): Item[] => [
      { group, count: alarms.length },
      ...alarms.map((alarm) => ({ group, alarm })),
    ]),
    [groups],
  );
  const offsets = useMemo(() => itemOffsets(items.map((i) => (i.alarm ? ROW_PX : GROUP_HEAD_PX))), [items]);
  const body = useRef<HTMLDivElement>(null);
  const [top, bottom] = useWindowRange(body);
  const [first, last] = visibleSlice(offsets, top - OVERSCAN_PX, bottom + OVERSCAN_PX);
  const rows = items.length - groups.length;
  return (
    <div className="alarm-list" role="table" aria-label="Alarm list" aria-rowcount={items.length + 1}
      data-alarm-count={rows}>
      <div role="row" className="alarm-list-head" aria-rowindex={1}>
        {["Alarm", "State", "Robot", "Patient", "Location", "Raised", ""].map((h, i) => (
          <span role="columnheader" key={i}>{h}</span>
        ))}
      </div>
      <div role="rowgroup" className="alarm-list-body" ref={body} style={{ height: offsets[items.length] }}>
        {items.slice(first, last).map((item, i) => {
          const index = first + i;
          const place = { top: offsets[index] };
          if (!item.alarm) {
            return (
              <div role="row" key={`group-${item.group}`} className={`group-head group-${item.group}`} style={place}
                data-group={item.group} aria-rowindex={index + 2}>
                <span role="rowheader">{GROUP_LABEL[item.group]} ({item.count})</span>
              </div>
            );
          }
          const alarm = item.alarm;
          return (
            <Row key={alarm.id} alarm={alarm} top={offsets[index]} rowIndex={index + 2} group={item.group}
              since={`${elapsed(alarm.raised_at, now)} ago`} ended={transportEndedText(alarm, now)}
              busy={busyId === alarm.id} onAcknowledge={onAcknowledge} onResolve={onResolve} />
          );
        })}
      </div>
    </div>
  );
}

/** The px range of the window over `element` ([0, window height] before it is laid out),
 * following scrolls and resizes (once per frame). */
function useWindowRange(element: RefObject<HTMLElement | null>): [number, number] {
  const [range, setRange] = useState<[number, number]>(() => [0, window.innerHeight]);
  useLayoutEffect(() => {
    let frame = 0;
    const measure = () => {
      frame = 0;
      const box = element.current?.getBoundingClientRect();
      if (!box) return;
      const next: [number, number] = [-box.top, window.innerHeight - box.top];
      setRange((old) => (old[0] === next[0] && old[1] === next[1] ? old : next));
    };
    const schedule = () => { if (!frame) frame = requestAnimationFrame(measure); };
    measure();
    window.addEventListener("scroll", schedule, { passive: true });
    window.addEventListener("resize", schedule);
    return () => {
      cancelAnimationFrame(frame);
      window.removeEventListener("scroll", schedule);
      window.removeEventListener("resize", schedule);
    };
  }, [element]);
  return range;
}

interface RowProps {
  alarm: Alarm;
  top: number;
  rowIndex: number;
  group: TriageGroup;
  since: string;
  ended: string | null;
  busy: boolean;
  onAcknowledge(alarm: Alarm): void;
  onResolve(alarm: Alarm): void;
}

// Memoised: of the rows drawn, only those whose text or place changed render again.
const Row = memo(function Row({ alarm, top, rowIndex, group, since, ended, busy, onAcknowledge, onResolve }: RowProps) {
  const stored = isStored(alarm);
  return (
    <div role="row" className={`alarm-row alarm-${styleOf(alarm)} state-${alarm.state} group-${group}`}
      data-alarm-id={alarm.id} data-state={alarm.state} data-stored={stored ? "true" : "false"}
      style={{ top }} aria-rowindex={rowIndex}>
      <span role="cell" className="kind" title={alarmTitle(alarm)}>{alarmTitle(alarm)}</span>
      <span role="cell" className="state" title={stateText(alarm)}>{stateText(alarm)}</span>
      <span role="cell">{robotLabel(alarm)}</span>
      <span role="cell">{alarm.patient ?? "–"}</span>
      <span role="cell" title={[alarm.location, ended].filter(Boolean).join(" · ")}>
        {alarm.location ?? "–"}{ended && <span className="transport-ended"> · {ended}</span>}
      </span>
      <span role="cell" className="since" title={alarm.raised_at}>{since}</span>
      <span role="cell" className="actions">
        {alarm.kind !== "storage_stalled" && mayAcknowledge(alarm) && (
          <button type="button" className="ack" disabled={busy} onClick={() => onAcknowledge(alarm)}>Acknowledge</button>
        )}
        {alarm.kind !== "storage_stalled" && <button type="button" className="resolve" disabled={busy} onClick={() => onResolve(alarm)}>Resolve…</button>}
        {stored && <Link to={`/nurse/alarms/${alarm.id}`}>Replay</Link>}
        {!stored && <span className="unstored">Not yet stored</span>}
      </span>
    </div>
  );
});
