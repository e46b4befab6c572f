import { useEffect, useState } from "react";
import { api, errorMessage } from "../api/client";
import { DataTable } from "./DataTable";

/** Annotation workspace (placeholder: lists the videos; the labelling tool lands with its issue). */
export function AnnotatePage() {
  const [videos, setVideos] = useState<Record<string, unknown>[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    void api.GET("/api/videos").then(({ data, error }) => {
      if (data) setVideos(data as unknown as Record<string, unknown>[]);
      else setError(errorMessage(error, "Could not load videos"));
    });
  }, []);
  return (
    <main className="page">
      <h1>Annotation</h1>
      <h2>Videos</h2>
      {error && <p role="alert" className="error">{error}</p>}
      {videos ? <DataTable rows={videos} label="Videos" /> : !error && <p className="muted">Loading…</p>}
    </main>
  );
}
