import { useEffect, useState } from "react";
import { Link } from "react-router-dom";
import { api, errorMessage } from "../api/client";
import type { components } from "../api/schema";
import { GROUP_LABEL, KIND_LABEL } from "../lib/alarmBoard";
import { clockTime } from "../lib/time";
import { robotLabel } from "../lib/dispositions";
import { handoverSections, secondsText, shareText } from "./handoverLogic";
import { verdictText } from "./labels";

type Handover = components["schemas"]["HandoverOut"];

/** The shift at a glance for the nurse who takes over: open, missed, acknowledged-unresolved and
 * escalated alarms, per robot, with the shift's fatigue figures; CSV export and print. */
export function HandoverPage() {
  const [report, setReport] = useState<Handover | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [exporting, setExporting] = useState(false);

  useEffect(() => {
    let live = true;
    void api.GET("/api/handover").then(({ data, error }) => {
      if (!live) return;
      if (data) { setReport(data); setError(null); }
      else setError(errorMessage(error, "Could not load the handover"));
    });
    return () => { live = false; };
  }, []);

  async function exportCsv() {
    setExporting(true);
    const { data, error, response } = await api.GET("/api/handover.csv", { parseAs: "text" });
    setExporting(false);
    if (typeof data !== "string") { setError(errorMessage(error, "Could not export the handover")); return; }
    const name = /filename="([^"]+)"/.exec(response.headers.get("Content-Disposition") ?? "")?.[1] ?? "handover.csv";
    const url = URL.createObjectURL(new Blob([data], { type: "text/csv" }));
    const link = document.createElement("a");
    link.href = url;
    link.download = name;
    document.body.appendChild(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10_000);
  }

  const f = report?.fatigue;
  return (
    <main className="page handover">
      <h1>Shift handover</h1>
      {error && <p role="alert" className="error">{error}</p>}
      {report && f && (
        <>
          <p className="muted">
            {report.ward ?? "All wards"} · {report.shift ? `${report.shift} shift, ` : ""}from {clockTime(report.since)} to {clockTime(report.until)}
          </p>
          <div className="no-print handover-actions">
            <button type="button" className="primary" disabled={exporting} onClick={() => void exportCsv()}>Export CSV</button>{" "}
            <button type="button" onClick={() => window.print()}>Print</button>
          </div>
          <h2>Now</h2>
          <div className="figures" data-testid="handover-counts">
            <span className="figure"><b>{report.counts.open}</b>open</span>
            <span className="figure"><b>{report.counts.missed}</b>missed: needs review</span>
            <span className="figure"><b>{report.counts.acknowledged_unresolved}</b>acknowledged, unresolved</span>
            <span className="figure"><b>{report.counts.escalated}</b>escalated</span>
            <span className="figure"><b>{report.counts.ever_missed}</b>missed in all</span>
          </div>
          <h2>Fatigue figures of the shift</h2>
          <table aria-label="Fatigue figures">
            <tbody>
              <tr><th>Alarms raised</th><td>{f.alarms} ({f.emergencies} Emergency, {f.technical} technical, {f.pauses} Pause)</td></tr>
              <tr><th>Non-actionable share</th><td>{shareText(f.non_actionable, f.resolved_with_verdict)}</td></tr>
              <tr><th>Time to acknowledge</th><td>p50 {secondsText(f.ack_p50_s)} · p90 {secondsText(f.ack_p90_s)} · p95 {secondsText(f.ack_p95_s)} (n={f.alarms}; unacknowledged ones at their wait so far)</td></tr>
              <tr><th>Escalated / missed</th><td>{f.escalated} / {f.missed}</td></tr>
            </tbody>
          </table>
          <h2>Per robot</h2>
          <table aria-label="Per robot">
            <thead><tr><th>Robot</th><th>Alarms</th><th>Open</th><th>Missed</th><th>Acknowledged</th><th>Resolved</th><th>Escalated</th></tr></thead>
            <tbody>
              {report.per_robot.map((r) => (
                <tr key={r.robot_id ?? "ward"}><td>{r.robot_id ?? "– (ward system)"}</td><td>{r.alarms}</td><td>{r.open}</td><td>{r.missed}</td>
                  <td>{r.acknowledged_unresolved}</td><td>{r.resolved}</td><td>{r.escalated}</td></tr>
              ))}
            </tbody>
          </table>
          {handoverSections(report.alarms).map(({ section, title, rows }) => (
            <section key={section} aria-label={title} data-section={section}>
              <h2>{title} ({rows.length})</h2>
              <table>
                <thead><tr><th>Alarm</th><th>Robot</th><th>Patient</th><th>Location</th><th>Raised</th><th>Escalation</th><th>Verdict</th></tr></thead>
                <tbody>
                  {rows.map(({ alarm, was_missed }) => (
                    <tr key={alarm.id} data-alarm-id={alarm.id}>
                      <td><Link to={`/nurse/alarms/${alarm.id}`}>{KIND_LABEL[alarm.kind]} #{alarm.id}</Link></td>
                      <td>{robotLabel(alarm)}</td><td>{alarm.patient ?? "–"}</td><td>{alarm.location ?? "–"}</td>
                      <td>{clockTime(alarm.raised_at)}</td>
                      <td>{alarm.escalation_level ? `level ${alarm.escalation_level}` : "–"}{was_missed ? " · missed" : ""}</td>
                      <td>{verdictText(alarm.verdict, alarm.reason)}</td>
                    </tr>
                  ))}
                </tbody>
              </table>
            </section>
          ))}
          <p className="muted">Missed = {GROUP_LABEL.missed.toLowerCase()}: an Emergency not acknowledged after the last escalation level.</p>
        </>
      )}
    </main>
  );
}
