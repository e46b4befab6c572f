import { useEffect, useRef } from "react";
import type { Alarm } from "../api/types";
import type { LinkStatus } from "../lib/alarmSocket";
import { alarmNotice, newNotices, showNotice } from "../lib/notify";

/** A system notification for each alarm that arrives (or Emergency that escalates) while the
 * page is in the background. What the board held when it first went live is not news. */
export function useAlarmNotifications(alarms: Alarm[], status: LinkStatus): void {
  const seen = useRef<Map<string, number> | null>(null);
  useEffect(() => {
    if (status !== "live") return;
    if (seen.current === null) {
      seen.current = new Map();
      newNotices(alarms, seen.current);
      return;
    }
    const fresh = newNotices(alarms, seen.current);
    if (document.visibilityState !== "hidden") return;
    for (const alarm of fresh) void showNotice(alarmNotice(alarm));
  }, [alarms, status]);
}
