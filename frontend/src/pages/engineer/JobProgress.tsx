import type { Job } from "./types";

export function JobProgress({ job }: { job: Job }) {
  const pct = Math.round(job.progress * 100);
  return (
    <div className={`job-progress status-${job.status}`} aria-label={`job ${job.id} progress`}>
      <progress max={100} value={pct} /> <span>{pct}%</span>{" "}
      <span className="pill">{job.status}</span> <span className="muted">{job.message}</span>
    </div>
  );
}
