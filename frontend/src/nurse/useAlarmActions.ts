import { useCallback, useState } from "react";
import { api, errorMessage } from "../api/client";
import type { Alarm } from "../api/types";
import type { Resolution } from "./ResolveDialog";

/** Acknowledge and resolve, wherever the nurse looks at an alarm (board card or replay page). */
export function useAlarmActions(onUpdated: (alarm: Alarm) => void) {
  const [busyId, setBusyId] = useState<number | null>(null);
  const [error, setError] = useState<string | null>(null);

  const acknowledge = useCallback(
    async (alarm: Alarm) => {
      setBusyId(alarm.id);
      setError(null);
      const { data, error } = await api.POST("/api/alarms/{alarm_id}/acknowledge", {
        params: { path: { alarm_id: alarm.id } },
      });
      setBusyId(null);
      if (data) onUpdated(data);
      else setError(errorMessage(error, `Could not acknowledge alarm ${alarm.id}`));
    },
    [onUpdated],
  );

  /** True when the alarm was resolved. */
  const resolve = useCallback(
    async (alarm: Alarm, resolution: Resolution): Promise<boolean> => {
      setBusyId(alarm.id);
      setError(null);
      const { data, error } = await api.POST("/api/alarms/{alarm_id}/resolve", {
        params: { path: { alarm_id: alarm.id } },
        body: resolution,
      });
      setBusyId(null);
      if (data) onUpdated(data);
      else setError(errorMessage(error, `Could not resolve alarm ${alarm.id}`));
      return !!data;
    },
    [onUpdated],
  );

  return { busyId, error, setError, acknowledge, resolve };
}
