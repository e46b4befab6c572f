import { memo } from "react";
import { Link } from "react-router-dom";
import type { Alarm } from "../api/types";
import { alarmTitle, GROUP_LABEL, isRealarmed, isStored, styleOf, transportEndedText, type TriageGroup } from "../lib/alarmBoard";
import { elapsed } from "../lib/time";

interface Props {
  groups: { group: TriageGroup; alarms: Alarm[] }[];
  now: number;
  busyId: number | null;
  onAcknowledge(alarm: Alarm): void;
  onResolve(alarm: Alarm): void;
}

/** What the state column says: "Missed: needs review", "Escalated ×3", "Acknowledged by ana"… */
export function stateText(alarm: Alarm): string {
  if (alarm.state === "missed") return "Missed: needs review";
  if (isRealarmed(alarm)) return "Re-alarm";
  if (alarm.state === "acknowledged") return `Acknowledged by ${alarm.acknowledged_by ?? "?"}`;
  if (alarm.escalation_level > 0) return `Escalated${alarm.escalation_level > 1 ? ` ×${alarm.escalation_level}` : ""}`;
  return "New";
}

/** The compact board for many alarms: one row each, grouped in triage order. Rows are grid
 * boxes, not table rows, so the browser can skip laying out those off screen. */
export function AlarmList({ groups, now, busyId, onAcknowledge, onResolve }: Props) {
  return (
    <div className="alarm-list" role="table" aria-label="Alarm list">
      <div role="row" className="alarm-list-head">
        {["Alarm", "State", "Robot", "Patient", "Location", "Raised", ""].map((h, i) => (
          <span role="columnheader" key={i}>{h}</span>
        ))}
      </div>
      {groups.map(({ group, alarms }) => (
        <div role="rowgroup" key={group} data-group={group} className={`group-${group}`} aria-label={GROUP_LABEL[group]}>
          <div role="row" className="group-head"><span role="rowheader">{GROUP_LABEL[group]} ({alarms.length})</span></div>
          {alarms.map((alarm) => (
            <Row key={alarm.id} alarm={alarm} since={`${elapsed(alarm.raised_at, now)} ago`}
              ended={transportEndedText(alarm, now)} busy={busyId === alarm.id}
              onAcknowledge={onAcknowledge} onResolve={onResolve} />
          ))}
        </div>
      ))}
    </div>
  );
}

interface RowProps {
  alarm: Alarm;
  since: string;
  ended: string | null;
  busy: boolean;
  onAcknowledge(alarm: Alarm): void;
  onResolve(alarm: Alarm): void;
}

// Memoised: with hundreds of rows only those whose text changed render again each second.
const Row = memo(function Row({ alarm, since, ended, busy, onAcknowledge, onResolve }: RowProps) {
  const stored = isStored(alarm);
  return (
    <div role="row" className={`alarm-row alarm-${styleOf(alarm)} state-${alarm.state}`} data-alarm-id={alarm.id}
      data-state={alarm.state} data-stored={stored ? "true" : "false"}>
      <span role="cell" className="kind">{alarmTitle(alarm)}</span>
      <span role="cell" className="state">{stateText(alarm)}</span>
      <span role="cell">{alarm.robot_id}</span>
      <span role="cell">{alarm.patient ?? "–"}</span>
      <span role="cell">{alarm.location ?? "–"}{ended && <span className="transport-ended"> · {ended}</span>}</span>
      <span role="cell" className="since" title={alarm.raised_at}>{since}</span>
      <span role="cell" className="actions">
        {stored && (alarm.state === "open" || alarm.state === "missed") && (
          <button type="button" className="ack" disabled={busy} onClick={() => onAcknowledge(alarm)}>Acknowledge</button>
        )}
        {stored && <button type="button" className="resolve" disabled={busy} onClick={() => onResolve(alarm)}>Resolve…</button>}
        {stored && <Link to={`/nurse/alarms/${alarm.id}`}>Replay</Link>}
        {!stored && <span className="unstored">Not yet stored</span>}
      </span>
    </div>
  );
});
