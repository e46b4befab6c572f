import { useEffect, useState } from "react";
import { Link } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { jobResultLink } from "../../lib/registry";
import { JobProgress } from "./JobProgress";
import type { Job } from "./types";
import { isFinished, useJob } from "./useJobPolling";

export function JobsPage() {
  const [jobs, setJobs] = useState<Job[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [open, setOpen] = useState<number | null>(null);
  const detail = useJob(open);
  const load = () =>
    api.GET("/api/jobs").then(({ data, error }) => {
      if (data) setJobs(data); else setError(errorMessage(error, "Could not load jobs"));
    });
  useEffect(() => {
    void load();
    const timer = setInterval(load, 1000);
    return () => clearInterval(timer);
  }, []);
  async function cancel(id: number) {
    const { error } = await api.POST("/api/jobs/{job_id}/cancel", { params: { path: { job_id: id } } });
    if (error) setError(errorMessage(error, "Could not cancel"));
    void load();
  }
  return (
    <>
      <h1>Jobs</h1>
      {error && <p role="alert" className="error">{error}</p>}
      {jobs === null ? <p className="muted">Loading…</p> : jobs.length === 0 ? <p className="empty">No jobs yet.</p> : (
        <table className="table" aria-label="Jobs">
          <thead><tr><th>#</th><th>Kind</th><th>Progress</th><th>Result</th><th>Worker</th><th>Created</th><th /></tr></thead>
          <tbody>{jobs.map((j) => (
            <tr key={j.id}>
              <td>{j.id}</td><td>{j.kind}</td><td><JobProgress job={j} /></td>
              <td>{(() => {
                const link = jobResultLink(j.kind, j.result as Record<string, unknown> | null);
                return link ? <Link to={`/engineer/models/${link.modelId}`}>{link.text}</Link> : "–";
              })()}</td>
              <td>{j.worker_id ?? "–"}{j.attempts > 1 ? ` (attempt ${j.attempts})` : ""}</td>
              <td>{new Date(j.created_at).toLocaleString()}</td>
              <td>
                <button type="button" onClick={() => setOpen(open === j.id ? null : j.id)}>Log</button>{" "}
                {!isFinished(j.status) && !j.cancel_requested && <button type="button" onClick={() => cancel(j.id)}>Cancel</button>}
              </td>
            </tr>))}</tbody>
        </table>
      )}
      {detail && <pre className="job-log" aria-label={`log of job ${detail.id}`}>{detail.log}</pre>}
    </>
  );
}
