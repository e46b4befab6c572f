import { useEffect, useState } from "react";
import { api } from "../../api/client";
import type { JobDetail } from "./types";

const FINISHED = new Set(["succeeded", "failed", "cancelled"]);

/** Follow one job live (progress, message, log) until it finishes. */
export function useJob(jobId: number | null, periodMs = 1000): JobDetail | null {
  const [job, setJob] = useState<JobDetail | null>(null);
  useEffect(() => {
    if (jobId === null) { setJob(null); return; }
    let live = true;
    let timer: ReturnType<typeof setTimeout>;
    const poll = async () => {
      const { data } = await api.GET("/api/jobs/{job_id}", { params: { path: { job_id: jobId } } });
      if (!live) return;
      if (data) setJob(data);
      if (!data || !FINISHED.has(data.status)) timer = setTimeout(poll, periodMs);
    };
    void poll();
    return () => { live = false; clearTimeout(timer); };
  }, [jobId, periodMs]);
  return job;
}

export const isFinished = (status: string) => FINISHED.has(status);
