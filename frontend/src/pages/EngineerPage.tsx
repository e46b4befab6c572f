import { useEffect, useState } from "react";
import { api, errorMessage } from "../api/client";
import { DataTable } from "./DataTable";

/** Engineering workspace (placeholder: lists the robots; models and deployments land later). */
export function EngineerPage() {
  const [robots, setRobots] = useState<Record<string, unknown>[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    void api.GET("/api/robots").then(({ data, error }) => {
      if (data) setRobots(data as unknown as Record<string, unknown>[]);
      else setError(errorMessage(error, "Could not load robots"));
    });
  }, []);
  return (
    <main className="page">
      <h1>Engineering</h1>
      <h2>Robots</h2>
      {error && <p role="alert" className="error">{error}</p>}
      {robots ? <DataTable rows={robots} label="Robots" /> : !error && <p className="muted">Loading…</p>}
    </main>
  );
}
