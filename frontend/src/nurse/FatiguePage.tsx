import { useEffect, useState } from "react";
import { api, errorMessage } from "../api/client";
import type { components } from "../api/schema";
import { duration } from "../lib/time";
import { BarChart } from "./BarChart";

type Fatigue = components["schemas"]["FatigueOut"];

const PERIODS = [
  { days: 1, label: "last 24 h" },
  { days: 7, label: "last 7 days" },
  { days: 30, label: "last 30 days" },
];

const pct = (v: number) => `${Math.round(v * 100)} %`;
/** Fewer resolved or acknowledged alarms than this and a share or median says little. */
const SMALL_SAMPLE = 5;
const n = (count: number) => ` (n=${count}${count < SMALL_SAMPLE ? ", few" : ""})`;
const secs = duration;

/** Alarm fatigue: load per shift and ward, share of false alarms and time to acknowledge. */
export function FatiguePage() {
  const [days, setDays] = useState(7);
  const [stats, setStats] = useState<Fatigue | null>(null);
  const [error, setError] = useState<string | null>(null);

  useEffect(() => {
    let live = true;
    const since = new Date(Date.now() - days * 86400_000).toISOString();
    void api.GET("/api/alarm-fatigue", { params: { query: { since } } }).then(({ data, error }) => {
      if (!live) return;
      if (data) { setStats(data); setError(null); }
      else setError(errorMessage(error, "Could not load alarm statistics"));
    });
    return () => { live = false; };
  }, [days]);

  const shiftLabel = (s: Fatigue["shifts"][number]) =>
    `${new Date(s.shift_start).toLocaleDateString(undefined, { month: "short", day: "numeric", timeZone: "UTC" })} ${s.shift} · ${s.ward ?? "no ward"}`;
  const modelLabel = (m: Fatigue["by_model"][number]) => m.model_version ?? "unknown";

  return (
    <main className="page fatigue">
      <h1>Alarm fatigue</h1>
      <label>Period{" "}
        <select value={days} onChange={(e) => setDays(Number(e.target.value))}>
          {PERIODS.map((p) => <option key={p.days} value={p.days}>{p.label}</option>)}
        </select>
      </label>
      <p className="muted">Shifts: early 06–14, late 14–22, night 22–06 (server time, UTC).</p>
      {error && <p role="alert" className="error">{error}</p>}
      {stats && (
        <div className="charts">
          <BarChart title="Alarms per shift and ward" integer
            data={stats.shifts.map((s) => ({ key: `${s.shift_start}-${s.ward}`, label: shiftLabel(s), value: s.alarms }))} />
          <BarChart title="Share resolved as false alarm, per shift and ward (n = resolved alarms)" max={1} format={pct} color="#d97706"
            data={stats.shifts.filter((s) => s.resolved > 0).map((s) => ({ key: `${s.shift_start}-${s.ward}`,
              label: shiftLabel(s) + n(s.resolved), value: s.false_alarms / s.resolved }))} />
          <BarChart title="Median time to acknowledge, per shift and ward (n = alarms, unacknowledged ones at their wait so far)" format={secs} color="#059669"
            data={stats.shifts.filter((s) => s.median_ack_s != null)
              .map((s) => ({ key: `${s.shift_start}-${s.ward}`, label: shiftLabel(s) + n(s.acknowledged + s.unacknowledged),
                value: s.median_ack_s! }))} />
          <BarChart title="Alarms by model version" integer
            data={stats.by_model.map((m) => ({ key: modelLabel(m), label: modelLabel(m), value: m.alarms }))} />
          <BarChart title="Share false by model version (n = resolved alarms)" max={1} format={pct} color="#d97706"
            data={stats.by_model.filter((m) => m.false_share != null)
              .map((m) => ({ key: modelLabel(m), label: modelLabel(m) + n(m.resolved), value: m.false_share! }))} />
          <BarChart title="Median time to acknowledge by model version" format={secs} color="#059669"
            data={stats.by_model.filter((m) => m.median_ack_s != null)
              .map((m) => ({ key: modelLabel(m), label: modelLabel(m) + n(m.acknowledged + m.unacknowledged),
                value: m.median_ack_s! }))} />
        </div>
      )}
      {stats && (
        <table className="videos" aria-label="Sample sizes">
          <caption>Every figure with its sample size (“few”: fewer than {SMALL_SAMPLE}, read with care)</caption>
          <thead>
            <tr><th>Shift · ward</th><th>Alarms</th><th>Resolved</th><th>False alarms</th><th>False share</th>
              <th>Acknowledged</th><th>Never acknowledged</th><th>Median time to acknowledge</th></tr>
          </thead>
          <tbody>
            {stats.shifts.map((s) => (
              <tr key={`${s.shift_start}-${s.ward}`} data-testid="fatigue-row">
                <td>{shiftLabel(s)}</td><td>{s.alarms}</td><td>{s.resolved}</td><td>{s.false_alarms}</td>
                <td>{s.resolved ? `${pct(s.false_alarms / s.resolved)}${n(s.resolved)}` : "–"}</td>
                <td>{s.acknowledged}</td><td>{s.unacknowledged}</td>
                <td>{s.median_ack_s != null ? `${secs(s.median_ack_s)}${n(s.acknowledged + s.unacknowledged)}` : "–"}</td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
    </main>
  );
}
