import { useEffect, useState } from "react";
import { Link } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import type { Agreement, LabellingVideo } from "./types";

function ms(value: number | null | undefined): string {
  return value === null || value === undefined ? "–" : `${value > 0 ? "+" : ""}${value.toFixed(0)} ms`;
}

/** Two annotators of one video: Cohen's kappa per label and onset/offset differences. */
export function AgreementPage() {
  const [videos, setVideos] = useState<LabellingVideo[]>([]);
  const [videoId, setVideoId] = useState<number | null>(null);
  const [find, setFind] = useState("");
  const [annotators, setAnnotators] = useState<string[]>([]);
  const [a, setA] = useState("");
  const [b, setB] = useState("");
  const [result, setResult] = useState<Agreement | null>(null);
  const [error, setError] = useState<string | null>(null);

  useEffect(() => {
    void api.GET("/api/labelling/videos").then(({ data }) => data && setVideos(data));
  }, []);
  useEffect(() => {
    if (videoId === null) return;
    setResult(null);
    void api
      .GET("/api/labelling/videos/{video_id}/annotators", { params: { path: { video_id: videoId } } })
      .then(({ data }) => {
        const names = data?.annotators ?? [];
        setAnnotators(names);
        setA(names[0] ?? "");
        setB(names[1] ?? "");
      });
  }, [videoId]);
  useEffect(() => {
    if (videoId === null || !a || !b || a === b) return;
    void api
      .GET("/api/labelling/videos/{video_id}/agreement", {
        params: { path: { video_id: videoId }, query: { a, b } },
      })
      .then(({ data, error }) => {
        setResult(data ?? null);
        setError(data ? null : errorMessage(error, "Could not compute agreement"));
      });
  }, [videoId, a, b]);

  return (
    <main className="page">
      <div className="label-head">
        <Link to="/annotate">← Videos</Link>
        <h1>Annotator agreement</h1>
      </div>
      <div className="filters">
        <label>Find video
          <input type="search" value={find} onChange={(e) => setFind(e.target.value)} placeholder="part of the name" />
        </label>
        <label>Video
          <select value={videoId ?? ""} onChange={(e) => setVideoId(Number(e.target.value) || null)}>
            <option value="">choose…</option>
            {videos.filter((v) => v.id === videoId || v.name.toLowerCase().includes(find.toLowerCase()))
              .map((v) => <option key={v.id} value={v.id}>{v.name}</option>)}
          </select>
        </label>
        <label>Annotator A
          <select value={a} onChange={(e) => setA(e.target.value)}>
            {annotators.map((n) => <option key={n}>{n}</option>)}
          </select>
        </label>
        <label>Annotator B
          <select value={b} onChange={(e) => setB(e.target.value)}>
            {annotators.map((n) => <option key={n}>{n}</option>)}
          </select>
        </label>
      </div>
      {videoId !== null && annotators.length < 2 && (
        <p className="empty">This video has fewer than two annotators.</p>
      )}
      {error && <p role="alert" className="error">{error}</p>}
      {result && (
        <>
          <p>
            {result.frames_compared} frames labelled by both · overall Cohen's kappa{" "}
            <strong>{result.overall_kappa?.toFixed(3) ?? "undefined"}</strong>
          </p>
          <h2>Per label (frame agreement)</h2>
          <table className="videos" aria-label="Kappa per label">
            <thead><tr><th>Label</th><th>kappa</th><th>frames A</th><th>frames B</th></tr></thead>
            <tbody>
              {result.labels.map((l) => (
                <tr key={l.label_key}>
                  <td>{l.label_key}</td><td>{l.kappa?.toFixed(3) ?? "–"}</td>
                  <td>{l.frames_a}</td><td>{l.frames_b}</td>
                </tr>
              ))}
            </tbody>
          </table>
          <h2>Fall stages: onset and offset (B − A)</h2>
          <table className="videos" aria-label="Fall stage timing">
            <thead><tr><th>Stage</th><th>onset A</th><th>onset B</th><th>Δ onset</th><th>Δ offset</th></tr></thead>
            <tbody>
              {result.stages.map((s) => (
                <tr key={s.label_key}>
                  <td>{s.label_key}</td>
                  <td>{s.onset_a_ms?.toFixed(0) ?? "–"} ms</td>
                  <td>{s.onset_b_ms?.toFixed(0) ?? "–"} ms</td>
                  <td>{ms(s.onset_diff_ms)}</td>
                  <td>{ms(s.offset_diff_ms)}</td>
                </tr>
              ))}
            </tbody>
          </table>
        </>
      )}
    </main>
  );
}
