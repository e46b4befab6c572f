import { useEffect, useState, type FormEvent } from "react";
import { Link, useNavigate } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { listView, statusText, type SortDirection } from "../../lib/registry";
import { Pager } from "../Pager";
import { JobProgress } from "./JobProgress";
import { fmt, type ModelSummary } from "./types";
import { useJob } from "./useJobPolling";

const SPECS = ["rf-default", "rf", "svm-paper", "svm", "mlp"];
const PAGE_SIZE = 25;

type SortColumn = "version" | "status" | "mode" | "falls" | "f1" | "robots" | "created";
const SORT_KEYS: Record<SortColumn, (m: ModelSummary) => string | number> = {
  version: (m) => m.version,
  status: (m) => statusText(m),
  mode: (m) => m.mode,
  falls: (m) => Number(m.gold?.falls_detected ?? -1),
  f1: (m) => Number(m.gold?.frame_f1 ?? -1),
  robots: (m) => m.robots_assigned,
  created: (m) => m.created_at,
};

export function RegistryPage() {
  const [models, setModels] = useState<ModelSummary[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [picked, setPicked] = useState<number[]>([]);
  const [spec, setSpec] = useState("rf-default");
  const [archives, setArchives] = useState<{ id: number; video_name: string; labelled_frames: number }[]>([]);
  const [archiveIds, setArchiveIds] = useState<number[]>([]);
  const [jobId, setJobId] = useState<number | null>(null);
  const job = useJob(jobId);
  const navigate = useNavigate();
  const [query, setQuery] = useState("");
  const [sort, setSort] = useState<{ column: SortColumn; direction: SortDirection }>({ column: "created", direction: "desc" });
  const [page, setPage] = useState(0);
  const view = listView(models ?? [], (m) => `${m.version} ${statusText(m)} ${m.mode} ${m.kind} ${m.inputs.join(" ")}`,
    query, SORT_KEYS[sort.column], sort.direction, page, PAGE_SIZE);
  const sortBy = (column: SortColumn) =>
    setSort((s) => ({ column, direction: s.column === column && s.direction === "asc" ? "desc" : "asc" }));
  const header = (column: SortColumn, label: string) => (
    <th aria-sort={sort.column === column ? (sort.direction === "asc" ? "ascending" : "descending") : undefined}>
      <button type="button" className="link" onClick={() => sortBy(column)}>
        {label}{sort.column === column ? (sort.direction === "asc" ? " ▲" : " ▼") : ""}
      </button>
    </th>
  );

  const load = () =>
    api.GET("/api/models").then(({ data, error }) => {
      if (data) { setModels(data); setError(null); } else setError(errorMessage(error, "Could not load models"));
    });
  useEffect(() => { void load(); }, []);
  useEffect(() => {
    void api.GET("/api/storage/archives").then(({ data }) => { if (data) setArchives(data.filter((a) => a.labelled_frames > 0)); });
  }, []);
  useEffect(() => { if (job?.status === "succeeded") void load(); }, [job?.status]);

  async function retrain(event: FormEvent) {
    event.preventDefault();
    const params = archiveIds.length ? { spec, archive_ids: archiveIds } : { spec };
    const { data, error } = await api.POST("/api/jobs", { body: { kind: "retrain", params } });
    if (data) setJobId(data.id); else setError(errorMessage(error, "Could not queue the retrain job"));
  }
  const toggle = (id: number) =>
    setPicked((p) => (p.includes(id) ? p.filter((x) => x !== id) : [...p.slice(-1), id]));

  return (
    <>
      <h1>Model registry</h1>
      <form className="filters" onSubmit={retrain} aria-label="Retrain">
        <label>Model family
          <select value={spec} onChange={(e) => setSpec(e.target.value)} name="spec">
            {SPECS.map((s) => <option key={s}>{s}</option>)}
          </select>
        </label>
        {archives.length > 0 && (
          <label>Also train on archived videos
            <select multiple name="archive_ids" value={archiveIds.map(String)}
              onChange={(e) => setArchiveIds(Array.from(e.target.selectedOptions, (o) => Number(o.value)))}>
              {archives.map((a) => <option key={a.id} value={a.id}>{a.video_name} ({a.labelled_frames} labelled frames)</option>)}
            </select>
          </label>
        )}
        <button className="primary" type="submit">Retrain from accepted labels</button>
        {job && <JobProgress job={job} />}
      </form>
      {error && <p role="alert" className="error">{error}</p>}
      <p>
        <button type="button" disabled={picked.length !== 2}
          onClick={() => navigate(`/engineer/compare?a=${picked[0]}&b=${picked[1]}`)}>
          Compare the two selected
        </button>
      </p>
      <div className="filters">
        <label>Search models
          <input type="search" value={query} placeholder="version, status, mode…"
            onChange={(e) => { setQuery(e.target.value); setPage(0); }} />
        </label>
        <span className="muted" data-testid="model-count">{view.total} of {models?.length ?? 0} models</span>
      </div>
      {models === null ? <p className="muted">Loading…</p> : models.length === 0 ? <p className="empty">No models registered yet.</p> : (
        <div className="table-wrap">
          <table className="table" aria-label="Models">
            <thead><tr>
              <th>Pick</th>{header("version", "Version")}{header("status", "Status")}{header("mode", "Mode")}<th>Needs</th>
              {header("falls", "Gold falls")}<th>Gold false alarms</th>{header("f1", "Frame F1")}<th>Threshold</th>
              <th>Delay</th>{header("robots", "Robots")}{header("created", "Created")}
            </tr></thead>
            <tbody>
              {view.rows.map((m) => (
                <tr key={m.id}>
                  <td><input type="checkbox" aria-label={`pick ${m.version}`} checked={picked.includes(m.id)} onChange={() => toggle(m.id)} /></td>
                  <td><Link to={`/engineer/models/${m.id}`}>{m.version}</Link></td>
                  <td><span className={`pill status-${m.status}`}>{statusText(m)}</span></td>
                  <td>{m.mode}</td>
                  <td>{m.inputs.join(", ")}</td>
                  <td>{m.gold ? `${fmt(m.gold.falls_detected)}/${fmt(m.gold.falls_total)}` : "not evaluated"}</td>
                  <td>{m.gold ? `${fmt(m.gold.adl_false_alarms)}/${fmt(m.gold.adl_total)}` : "–"}</td>
                  <td>{fmt(m.gold?.frame_f1)}</td>
                  <td>{fmt(m.threshold)}</td>
                  <td>{m.delay_ms} ms</td>
                  <td>{m.robots_assigned}</td>
                  <td>{new Date(m.created_at).toLocaleString()}</td>
                </tr>
              ))}
            </tbody>
          </table>
          <Pager label="Model pages" page={view.page} pages={view.pages} onPage={setPage} />
        </div>
      )}
    </>
  );
}
