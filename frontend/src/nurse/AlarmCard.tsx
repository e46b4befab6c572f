import { Link } from "react-router-dom";
import type { Alarm } from "../api/types";
import { robotStateText } from "../lib/robotState";
import { alarmTitle, isRealarmed, isStored, KIND_LABEL, mayAcknowledge, styleOf, transportEndedText } from "../lib/alarmBoard";
import { elapsed } from "../lib/time";
import { dispositionLine, rejectedOnPhone, robotLabel } from "../lib/dispositions";

interface Props {
  alarm: Alarm;
  now: number;
  busy: boolean;
  onAcknowledge(alarm: Alarm): void;
  onResolve(alarm: Alarm): void;
}

export function AlarmCard({ alarm, now, busy, onAcknowledge, onResolve }: Props) {
  const style = styleOf(alarm);
  const stored = isStored(alarm);
  const summary = typeof alarm.details?.summary === "string" ? alarm.details.summary : null;
  const ended = transportEndedText(alarm, now);
  return (
    <article
      className={`alarm alarm-${style} state-${alarm.state}${isRealarmed(alarm) ? " realarmed" : ""}`}
      data-alarm-id={alarm.id}
      data-state={alarm.state}
      data-stored={stored ? "true" : "false"}
      aria-label={`${KIND_LABEL[alarm.kind]} alarm ${alarm.id}`}
    >
      <header>
        <span className="kind">{alarmTitle(alarm)}</span>
        {alarm.state === "missed" && (
          <span className="missed" title="Not acknowledged after the last escalation level">
            Missed: needs review
          </span>
        )}
        {alarm.state === "missed" && alarm.escalated_to && (
          <span className="escalated" data-testid="escalated-to" title="Nobody answered: called the next responder">
            Escalated to {alarm.escalated_to}
          </span>
        )}
        {alarm.escalation_level > 0 && alarm.state !== "missed" && (
          <span className="escalated" title="Not acknowledged in time: escalated">
            Escalated{alarm.escalation_level > 1 ? ` ×${alarm.escalation_level}` : ""}
          </span>
        )}
        {isRealarmed(alarm) && (
          <span className="escalated realarmed" title="Acknowledged but not resolved in time">
            Re-alarm
          </span>
        )}
        {!stored && alarm.kind !== "storage_stalled" && (
          <span className="unstored" title="Storage is stalled: this alarm reached you before it could be stored. It is stored as soon as storage recovers.">
            Not yet stored
          </span>
        )}
        <span className="since" title={alarm.raised_at}>{elapsed(alarm.raised_at, now)} ago</span>
      </header>
      {alarm.kind === "detection_degraded" && typeof alarm.details?.reason === "string" && alarm.details.reason && (
        <p className="technical-reason">{alarm.details.reason}</p>
      )}
      {(alarm.kind === "storage_stalled" || alarm.kind === "alarm_distribution_down") && summary && (
        <p className="technical-reason">{summary}</p>
      )}
      {ended && <p className="transport-ended">{ended[0].toUpperCase() + ended.slice(1)}</p>}
      <dl>
        <dt>Robot</dt><dd>{robotLabel(alarm)}</dd>
        {alarm.robot_state && (
          <><dt>Robot did</dt><dd className={`robot-state robot-${alarm.robot_state}`} data-testid="robot-state">
            {robotStateText(alarm.robot_state, alarm.robot_state_since)}</dd></>
        )}
        <dt>Patient</dt><dd>{alarm.patient ?? "–"}</dd>
        <dt>Location</dt><dd>{alarm.location ?? "–"}</dd>
        <dt className="alarm-detail-extra">Transport</dt><dd className="alarm-detail-extra">{alarm.transport_id ?? "–"}</dd>
        <dt className="alarm-detail-extra">Ward</dt><dd className="alarm-detail-extra">{alarm.ward ?? "–"}</dd>
        {alarm.state === "acknowledged" && (
          <>
            <dt>Acknowledged</dt>
            <dd>by {alarm.acknowledged_by ?? "?"}{alarm.acknowledged_at ? `, ${elapsed(alarm.acknowledged_at, now)} ago` : ""}</dd>
          </>
        )}
      </dl>
      {dispositionLine(alarm) && (
        <p className={`dispositions${rejectedOnPhone(alarm) ? " rejected" : ""}`} data-testid="dispositions">
          {dispositionLine(alarm)}
        </p>
      )}
      {alarm.kind === "storage_stalled" ? (
        <footer>
          <span className="unstored-note">Clears by itself when storage recovers.</span>
        </footer>
      ) : (
        <footer>
          {mayAcknowledge(alarm) && (
            <button type="button" className="ack" disabled={busy} onClick={() => onAcknowledge(alarm)}>
              Acknowledge
            </button>
          )}
          <button type="button" className="resolve" disabled={busy} onClick={() => onResolve(alarm)}>
            Resolve…
          </button>
          {stored ? <Link to={`/nurse/alarms/${alarm.id}`} className="replay-link">Replay</Link> : (
            // Storage is stalled: what the nurse does is kept and applied once the alarm is stored.
            <span className="unstored-note">Replay once stored; acknowledging works now.</span>
          )}
        </footer>
      )}
    </article>
  );
}
