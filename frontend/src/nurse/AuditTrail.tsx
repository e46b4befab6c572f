import { useEffect, useState } from "react";
import { api, errorMessage } from "../api/client";
import type { AlarmEvent } from "../api/types";
import { clockTime } from "../lib/time";

export function AuditTrail({ alarmId, refreshKey }: { alarmId: number; refreshKey?: unknown }) {
  const [events, setEvents] = useState<AlarmEvent[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    let live = true;
    void api.GET("/api/alarms/{alarm_id}/events", { params: { path: { alarm_id: alarmId } } })
      .then(({ data, error }) => {
        if (!live) return;
        if (data) setEvents(data);
        else setError(errorMessage(error, "Could not load the audit trail"));
      });
    return () => { live = false; };
  }, [alarmId, refreshKey]);
  if (error) return <p role="alert" className="error">{error}</p>;
  if (!events) return <p className="muted">Loading audit trail…</p>;
  return (
    <div className="table-wrap">
    <table className="table audit" aria-label="Audit trail">
      <thead><tr><th>When</th><th>Who</th><th>Action</th><th>State</th><th>Comment</th></tr></thead>
      <tbody>
        {events.map((e) => (
          <tr key={e.id}>
            <td>{clockTime(e.at)}</td>
            <td>{e.actor}</td>
            <td>{e.action}</td>
            <td>{e.from_state ? `${e.from_state} → ${e.to_state}` : e.to_state}</td>
            <td>{e.comment ?? ""}</td>
          </tr>
        ))}
      </tbody>
    </table>
    </div>
  );
}
