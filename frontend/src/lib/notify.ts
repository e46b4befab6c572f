// System notifications for alarms that arrive while the board is in the background (a nurse's
// phone in her pocket, another tab in front): the Notifications API, through the service
// worker where there is one (phones show notifications only from a service worker).
import type { Alarm } from "../api/types";
import { alarmTitle } from "./alarmBoard";
import { robotLabel } from "./dispositions";

/** An alarm's identity across its provisional and stored versions. */
const identity = (alarm: Alarm): string => alarm.key ?? `id:${alarm.id}`;

export interface AlarmNotice {
  title: string;
  options: NotificationOptions & { renotify?: boolean };
}

/** What the phone shows: kind and robot in the title, patient and place in the body. An
 * Emergency stays until the nurse acts on it (requireInteraction). */
export function alarmNotice(alarm: Alarm): AlarmNotice {
  const where = [alarm.patient ? `patient ${alarm.patient}` : null, alarm.location ? `at ${alarm.location}` : null]
    .filter(Boolean).join(" ");
  return {
    title: `${alarmTitle(alarm)} – robot ${robotLabel(alarm)}`,
    options: {
      body: where || `ward ${alarm.ward}`,
      tag: identity(alarm),
      renotify: true,
      requireInteraction: alarm.kind === "emergency",
      icon: "/icons/vigil-192.png",
      data: { url: alarm.id > 0 ? `/nurse/alarms/${alarm.id}` : "/nurse" },
    },
  };
}

/** The alarms to notify about: open ones not seen before (by identity), and Emergencies that
 * escalated since (a missed or escalated Emergency never gets quieter). `seen` maps identity
 * to the escalation level last notified and is updated in place. */
export function newNotices(alarms: Iterable<Alarm>, seen: Map<string, number>): Alarm[] {
  const out: Alarm[] = [];
  for (const alarm of alarms) {
    const id = identity(alarm);
    const level = alarm.escalation_level ?? 0;
    const before = seen.get(id);
    const calling = alarm.state === "open" || alarm.state === "missed";
    if (calling && (before === undefined || (alarm.kind === "emergency" && level > before))) out.push(alarm);
    seen.set(id, Math.max(level, before ?? -1));
  }
  return out;
}

/** Ask once, from a click (browsers allow the prompt only then). */
export async function askNotificationPermission(): Promise<NotificationPermission | "unsupported"> {
  if (typeof Notification === "undefined") return "unsupported";
  if (Notification.permission !== "default") return Notification.permission;
  return Notification.requestPermission();
}

export async function showNotice(notice: AlarmNotice): Promise<boolean> {
  if (typeof Notification === "undefined" || Notification.permission !== "granted") return false;
  const registration = await navigator.serviceWorker?.getRegistration?.();
  if (registration) {
    await registration.showNotification(notice.title, notice.options);
  } else {
    new Notification(notice.title, notice.options);
  }
  return true;
}
