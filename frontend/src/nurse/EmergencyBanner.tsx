import type { Alarm } from "../api/types";
import { elapsed } from "../lib/time";

interface Props {
  alarm: Alarm;
  others: number;
  now: number;
  busy: boolean;
  onAcknowledge(alarm: Alarm): void;
}

/** Sticky strip for the newest unacknowledged Emergency: robot, patient and location where the
 * eye already is, until someone acknowledges it (the tone repeats until then). */
export function EmergencyBanner({ alarm, others, now, busy, onAcknowledge }: Props) {
  // The list draws only the rows near the window: a row out of it is not in the page, and the
  // banner's alarm (the newest unacknowledged Emergency) is the board's first row, at its top.
  const show = () => {
    const row = document.querySelector(`[data-alarm-id='${alarm.id}']`);
    if (row) row.scrollIntoView({ block: "center" });
    else document.querySelector("main.board .board-head")?.scrollIntoView({ block: "start" });
  };
  return (
    <div className="banner banner-emergency" role="alert" data-testid="emergency-banner" data-alarm-id-banner={alarm.id}>
      <strong>Emergency</strong>
      <span>robot <b>{alarm.robot_id}</b></span>
      <span>patient <b>{alarm.patient ?? "unknown"}</b></span>
      <span>at <b>{alarm.location ?? "unknown location"}</b></span>
      <span className="since">{elapsed(alarm.raised_at, now)} ago</span>
      {others > 0 && <span className="others">+{others} more unacknowledged</span>}
      {alarm.stored !== false && (
        <button type="button" className="primary" disabled={busy} onClick={() => onAcknowledge(alarm)}>
          Acknowledge
        </button>
      )}
      <button type="button" onClick={show}>Show</button>
    </div>
  );
}
