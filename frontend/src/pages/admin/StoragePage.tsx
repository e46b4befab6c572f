// Admin: what is stored (frames and bytes per day and per robot, growth), what the next
// retention run will drop, past runs, and the Parquet archives (issue 20).
import { useEffect, useState } from "react";
import { api, errorMessage } from "../../api/client";
import type { components } from "../../api/schema";
import { BarChart } from "../../nurse/BarChart";
import { formatBytes, growthLine, keptInWords } from "../../lib/storage";

type Summary = components["schemas"]["StorageSummary"];
type Archive = components["schemas"]["ArchiveOut"];

const GROWTH_W = 560;
const GROWTH_H = 160;

function when(ts: number): string {
  return new Date(ts * 1000).toISOString().slice(0, 16).replace("T", " ") + " UTC";
}

export function StoragePage() {
  const [summary, setSummary] = useState<Summary | null>(null);
  const [archives, setArchives] = useState<Archive[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [notice, setNotice] = useState<string | null>(null);
  const [videoId, setVideoId] = useState("");

  const load = (fresh = false) => {
    void api.GET("/api/storage/summary", { params: { query: { fresh } } }).then(({ data, error }) => {
      if (data) setSummary(data); else setError(errorMessage(error, "Could not load the storage figures"));
    });
    void api.GET("/api/storage/archives").then(({ data, error }) => {
      if (data) setArchives(data); else setError(errorMessage(error, "Could not load the archives"));
    });
  };
  useEffect(() => load(), []);

  async function retention(dryRun: boolean) {
    setError(null);
    if (!dryRun && !window.confirm("Run retention now? Frames the policy does not keep are dropped.")) return;
    const { data, error } = await api.POST("/api/storage/retention", { body: { dry_run: dryRun } });
    if (data) setNotice(`${dryRun ? "Dry run" : "Retention run"} queued as job ${data.id}; its progress is on the jobs page.`);
    else setError(errorMessage(error, "Could not queue the retention run"));
  }

  async function archiveVideo() {
    setError(null);
    const id = Number(videoId);
    if (!Number.isInteger(id) || id < 1) { setError("video id: a positive whole number"); return; }
    const { data, error } = await api.POST("/api/storage/archives", { body: { video_id: id } });
    if (data) { setNotice(`Archived ${data.map((a) => a.video_name).join(", ")}`); load(true); }
    else setError(errorMessage(error, "Could not archive the video"));
  }

  async function importArchive(archive: Archive) {
    setError(null);
    const { data, error } = await api.POST("/api/storage/archives/{archive_id}/import",
      { params: { path: { archive_id: archive.id } } });
    if (data) { setNotice(`${data.video_name}: ${data.frames_in_database} frames in the database`); load(true); }
    else setError(errorMessage(error, `Could not import ${archive.video_name}`));
  }

  const next = summary?.next_run;
  const preview = next?.preview;
  return (
    <main className="page admin storage">
      <h1>Storage</h1>
      {error && <p role="alert" className="error">{error}</p>}
      {notice && <p role="status" className="notice">{notice}</p>}
      {summary === null ? <p className="muted">Loading…</p> : (
        <>
          <p>
            <strong>{summary.total_frames.toLocaleString("en")}</strong> frames,{" "}
            <strong>{formatBytes(summary.payload_bytes)}</strong> of frame data; the database
            takes <strong>{formatBytes(summary.database_bytes)}</strong> on disk ({summary.dialect}
            {summary.partitions !== null && summary.partitions !== undefined ? `, ${summary.partitions} day partitions` : ""}
            {summary.free_bytes ? `, ${formatBytes(summary.free_bytes)} free pages` : ""}).{" "}
            <span className="muted">Figures from {new Date(summary.computed_at).toLocaleTimeString()}</span>{" "}
            <button type="button" onClick={() => load(true)}>Refresh</button>
          </p>

          <h2>Next retention run</h2>
          <p aria-label="Next retention run">
            Policy: robot frames older than {summary.policy.days as number} days go, except alarm windows
            ({summary.policy.alarm_before_s as number} s before, {summary.policy.alarm_after_s as number} s after),
            labelled or split videos and registered models' training videos
            {(summary.policy.downsample_fps as number) > 0
              ? `; a copy at ${summary.policy.downsample_fps as number} frame/s stays ${summary.policy.downsample_days as number} more days` : ""}.
            {" "}{next?.due_at ? `Due ${new Date(next.due_at).toLocaleString()}` : "A run is queued or running"}; it
            looks at frames before {next ? when(next.cutoff_ts) : "–"}: at most{" "}
            <strong>{(next?.older_frames ?? 0).toLocaleString("en")}</strong> frames ({formatBytes(next?.older_bytes ?? 0)}).
          </p>
          {preview ? (
            <p aria-label="Dry run">
              Latest dry run ({new Date(preview.started_at).toLocaleString()}): would drop{" "}
              <strong>{preview.dropped_frames.toLocaleString("en")}</strong> frames ({formatBytes(preview.dropped_bytes)}),
              keeping {keptInWords(preview.kept as Record<string, number>)}.
            </p>
          ) : <p className="muted">No dry run yet.</p>}
          <p>
            <button type="button" onClick={() => void retention(true)}>Dry run</button>{" "}
            <button type="button" onClick={() => void retention(false)}>Run retention now</button>
          </p>

          <h2>Growth</h2>
          {summary.days.length === 0 ? <p className="muted">No robot frames yet.</p> : (
            <figure className="chart-figure">
              <figcaption>Stored robot frame bytes over time (cumulative, by UTC day)</figcaption>
              <svg viewBox={`-4 -4 ${GROWTH_W + 8} ${GROWTH_H + 8}`} className="chart" role="img" aria-label="Growth">
                <polyline fill="none" stroke="#2563eb" strokeWidth="2"
                  points={growthLine(summary.days, GROWTH_W, GROWTH_H)} />
              </svg>
              <p className="muted">{summary.days[0].day} – {summary.days[summary.days.length - 1].day}:{" "}
                {formatBytes(summary.days[summary.days.length - 1].cumulative_bytes)}</p>
            </figure>
          )}
          <BarChart title="Frames per day (robot frames)" integer
            data={summary.days.slice(-31).map((d) => ({ key: d.day, label: d.day.slice(5), value: d.frames }))} />

          <h2>Per day</h2>
          <table className="table" aria-label="Frames per day">
            <thead><tr><th>day (UTC)</th><th>frames</th><th>bytes</th></tr></thead>
            <tbody>
              {summary.days.slice().reverse().map((d) => (
                <tr key={d.day}><td>{d.day}</td><td>{d.frames.toLocaleString("en")}</td><td>{formatBytes(d.bytes)}</td></tr>
              ))}
            </tbody>
          </table>

          <h2>Per robot</h2>
          <table className="table" aria-label="Frames per robot">
            <thead><tr><th>robot</th><th>frames</th><th>bytes</th></tr></thead>
            <tbody>
              {summary.robots.map((r) => (
                <tr key={r.robot_id ?? "-"}>
                  <td>{r.robot_id ?? "imported recordings"}</td>
                  <td>{r.frames.toLocaleString("en")}</td><td>{formatBytes(r.bytes)}</td>
                </tr>
              ))}
            </tbody>
          </table>

          <h2>Retention runs</h2>
          <table className="table" aria-label="Retention runs">
            <thead><tr><th>started</th><th>kind</th><th>status</th><th>dropped</th><th>kept</th><th>message</th></tr></thead>
            <tbody>
              {summary.runs.map((r) => (
                <tr key={r.id}>
                  <td>{new Date(r.started_at).toLocaleString()}</td>
                  <td>{r.dry_run ? "dry run" : "run"}</td><td>{r.status}</td>
                  <td>{r.dropped_frames.toLocaleString("en")} ({formatBytes(r.dropped_bytes)})</td>
                  <td>{keptInWords(r.kept as Record<string, number>)}</td><td>{r.message}</td>
                </tr>
              ))}
            </tbody>
          </table>
        </>
      )}

      <h2>Archives</h2>
      <p>
        <label>Video id <input value={videoId} onChange={(e) => setVideoId(e.target.value)} inputMode="numeric" size={8} /></label>{" "}
        <button type="button" onClick={() => void archiveVideo()}>Archive to Parquet</button>
      </p>
      {archives === null ? <p className="muted">Loading…</p> : archives.length === 0 ? <p className="muted">No archives yet.</p> : (
        <table className="table" aria-label="Archives">
          <thead><tr><th>video</th><th>robot</th><th>frames</th><th>labelled</th><th>file</th><th>sha256</th><th>in database</th><th></th></tr></thead>
          <tbody>
            {archives.map((a) => (
              <tr key={a.id}>
                <td>{a.video_name}</td><td>{a.robot_id ?? "–"}</td>
                <td>{a.frame_count.toLocaleString("en")}</td><td>{a.labelled_frames.toLocaleString("en")}</td>
                <td>{formatBytes(a.bytes)}</td><td><code title={a.sha256}>{a.sha256.slice(0, 12)}</code></td>
                <td>{a.frames_in_database.toLocaleString("en")}</td>
                <td>{a.frames_in_database < a.frame_count && (
                  <button type="button" onClick={() => void importArchive(a)}>Import again</button>)}</td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
    </main>
  );
}
