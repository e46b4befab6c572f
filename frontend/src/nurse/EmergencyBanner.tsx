import type { Alarm } from "../api/types";
import { mayAcknowledge, type EmergencyBannerState } from "../lib/alarmBoard";
import { clockTime, elapsed } from "../lib/time";
import { robotLabel } from "../lib/dispositions";

interface Props {
  banner: EmergencyBannerState;
  now: number;
  busy: boolean;
  onAcknowledge(alarm: Alarm): void;
}

/** Sticky strip for the newest unanswered Emergency: robot, patient and location where the eye
 * already is. It stays while any Emergency of the ward is unanswered, missed ones included,
 * naming how many and the oldest (the tone repeats until then). */
export function EmergencyBanner({ banner, now, busy, onAcknowledge }: Props) {
  const { alarm, others, missed, oldest } = banner;
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
      <span>robot <b>{robotLabel(alarm)}</b></span>
      <span>patient <b>{alarm.patient ?? "unknown"}</b></span>
      <span>at <b>{alarm.location ?? "unknown location"}</b></span>
      <span className="since">{elapsed(alarm.raised_at, now)} ago</span>
      {others > 0 && (
        <span className="others" data-testid="banner-waiting">
          {others + 1} Emergencies unanswered{missed > 0 ? `, ${missed} missed` : ""}, oldest{" "}
          {clockTime(oldest.raised_at)} ({elapsed(oldest.raised_at, now)} ago)
        </span>
      )}
      {others === 0 && alarm.state === "missed" && (
        <span className="others" data-testid="banner-waiting">missed: nobody has answered it</span>
      )}
      {mayAcknowledge(alarm) && (
        <button type="button" className="primary" disabled={busy} onClick={() => onAcknowledge(alarm)}>
          Acknowledge
        </button>
      )}
      <button type="button" onClick={show}>Show</button>
    </div>
  );
}
