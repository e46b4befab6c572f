// What the hospital's alarm distribution (phones, pagers; IHE PCD ACM) reported of an alarm, in
// a nurse's words: "delivered to Anna's phone 12:03:05, accepted by Anna Berg 12:03:20".
import type { Alarm } from "../api/types";

type Disposition = NonNullable<Alarm["dispositions"]>[number];

function timeOfDay(iso: string): string {
  return new Date(iso).toLocaleTimeString(undefined, { hour: "2-digit", minute: "2-digit", second: "2-digit" });
}

function phrase(d: Disposition): string {
  const at = timeOfDay(d.at);
  switch (d.disposition) {
    case "delivered":
      return `delivered to ${d.device} ${at}`;
    case "read":
      return `read by ${d.clinician} ${at}`;
    case "accepted":
      return `accepted by ${d.clinician} ${at}`;
    case "rejected":
      return `rejected by ${d.clinician} ${at}`;
    default:
      return `${d.disposition} (${d.clinician}, ${d.device}) ${at}`;
  }
}

/** One line for the board, oldest report first; null when nothing came back (no alarm
 * distribution, or not yet delivered). */
export function dispositionLine(alarm: Pick<Alarm, "dispositions">): string | null {
  const reports = alarm.dispositions ?? [];
  if (reports.length === 0) return null;
  const line = reports.map(phrase).join(", ");
  return line[0].toUpperCase() + line.slice(1);
}

/** A rejected report is something a nurse must see: nobody on the phone took the alarm. */
export function rejectedOnPhone(alarm: Pick<Alarm, "dispositions">): boolean {
  const reports = alarm.dispositions ?? [];
  return reports.length > 0 && reports[reports.length - 1].disposition === "rejected";
}

/** The robot an alarm is about, or what it is about when it is about none (a ward's alarm
 * distribution going down). */
export function robotLabel(alarm: Pick<Alarm, "robot_id">): string {
  return alarm.robot_id ?? "– (ward system)";
}
