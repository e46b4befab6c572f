import { useEffect, useState } from "react";
import { api, errorMessage } from "../api/client";
import { DataTable } from "./DataTable";

type Rows = Record<string, unknown>[];

/** Annotation workspace (minimal: the review queue and the videos; the labelling tool comes
 * with its own issue). */
export function AnnotatePage() {
  const [queue, setQueue] = useState<Rows | null>(null);
  const [videos, setVideos] = useState<Rows | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    void api.GET("/api/review-queue").then(({ data, error }) => {
      if (data) setQueue(data as unknown as Rows);
      else setError(errorMessage(error, "Could not load the review queue"));
    });
    void api.GET("/api/videos").then(({ data, error }) => {
      if (data) setVideos(data as unknown as Rows);
      else setError(errorMessage(error, "Could not load videos"));
    });
  }, []);
  return (
    <main className="page">
      <h1>Annotation</h1>
      {error && <p role="alert" className="error">{error}</p>}
      <h2>Review queue</h2>
      <p className="muted">Pending labels; alarms that nurses rejected as false come first.</p>
      {queue ? <DataTable rows={queue} label="Review queue" /> : <p className="muted">Loading…</p>}
      <h2>Videos</h2>
      {videos ? <DataTable rows={videos} label="Videos" /> : <p className="muted">Loading…</p>}
    </main>
  );
}
