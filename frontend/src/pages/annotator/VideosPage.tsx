import { useCallback, useEffect, useRef, useState } from "react";
import { Link } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { currentToken } from "../../api/session";
import { useAuth } from "../../auth/AuthContext";
import { listView } from "../../lib/registry";
import { Pager } from "../Pager";
import type { LabellingVideo } from "./types";

type Split = LabellingVideo["split"];
type Mode = LabellingVideo["mode"];
const PAGE_SIZE = 50;
type ImportRequest = { file: File; format: string; mode: string };

/** The annotators' video list: progress, status, filters; admins change the split here. */
export function VideosPage() {
  const { user } = useAuth();
  const [videos, setVideos] = useState<LabellingVideo[] | null>(null);
  const [persons, setPersons] = useState<string[]>([]);
  const [mode, setMode] = useState<Mode | "">("");
  const [split, setSplit] = useState<Split | "">("");
  const [person, setPerson] = useState("");
  const [unreviewed, setUnreviewed] = useState(false);
  const [error, setError] = useState<string | null>(null);
  const [imported, setImported] = useState<string | null>(null);
  // An import refused because its video exists already: the file, to retry with merge or replace.
  const [taken, setTaken] = useState<(ImportRequest & { video: string }) | null>(null);
  const importForm = useRef<HTMLFormElement>(null);
  const [query, setQuery] = useState("");
  const [page, setPage] = useState(0);
  const view = listView(videos ?? [], (v) => `${v.name} ${v.person ?? ""} ${v.location ?? ""} ${v.status}`,
    query, (v) => v.name, "asc", page, PAGE_SIZE);

  const load = useCallback(async () => {
    const { data, error } = await api.GET("/api/labelling/videos", {
      params: {
        query: {
          mode: mode || undefined,
          split: split || undefined,
          person: person || undefined,
          unreviewed: unreviewed ? true : undefined,
        },
      },
    });
    if (data) setVideos(data);
    else setError(errorMessage(error, "Could not load videos"));
  }, [mode, split, person, unreviewed]);

  useEffect(() => void load(), [load]);
  useEffect(() => {
    void api.GET("/api/labelling/facets").then(({ data }) => data && setPersons(data.persons));
  }, []);

  const importFile = async (form: HTMLFormElement) => {
    const data = new FormData(form);
    const format = String(data.get("format"));
    const mode = String(data.get("mode") ?? "");
    const file = data.get("file");
    if (!(file instanceof File) || !file.size) return setError("Choose a file to import");
    await sendImport({ file, format, mode });
  };

  /** Posts the file; a new-video import whose video exists already is kept to be retried with
   * the annotator's choice (merge or replace) rather than refused in the API's words. */
  const sendImport = async (request: ImportRequest) => {
    setTaken(null);
    const body = new FormData();
    body.append("file", request.file);
    const query = new URLSearchParams({ format: request.format, ...(request.mode ? { mode: request.mode } : {}) });
    const response = await fetch(`/api/labelling/import?${query}`, {
      method: "POST",
      body,
      headers: { Authorization: `Bearer ${currentToken() ?? ""}` },
    });
    const result = await response.json();
    if (response.ok) {
      setError(null);
      setImported(
        `Imported into ${result.videos.join(", ")}: ${result.segments} new segment(s)` +
          (result.already_there ? `, ${result.already_there} already there (not added again)` : "") +
          (result.replaced ? `, ${result.replaced} imported segment(s) under review replaced` : ""),
      );
      importForm.current?.reset();
      await load();
    } else if (response.status === 409 && result?.code === "video_exists") {
      setError(null);
      setImported(null);
      setTaken({ ...request, video: String(result.video ?? "") });
    } else setError(errorMessage(result, "Import failed"));
  };

  const changeSplit = async (video: LabellingVideo, next: Split) => {
    const { error } = await api.PATCH("/api/labelling/videos/{video_id}", {
      params: { path: { video_id: video.id } },
      body: { split: next },
    });
    if (error) setError(errorMessage(error, "Could not change the split"));
    await load();
  };

  return (
    <main className="page">
      <div className="label-head">
        <h1>Videos to label</h1>
        <Link to="/annotate/review">Review queue</Link>
        <Link to="/annotate/agreement">Agreement</Link>
      </div>
      <div className="filters" role="group" aria-label="Filters">
        <label>Mode
          <select value={mode} onChange={(e) => setMode(e.target.value as Mode | "")}>
            <option value="">all</option>
            <option value="walking">walking</option>
            <option value="wheelchair">wheelchair</option>
            <option value="combined">combined</option>
          </select>
        </label>
        <label>Split
          <select value={split} onChange={(e) => setSplit(e.target.value as Split | "")}>
            <option value="">all</option>
            <option value="train">train</option>
            <option value="test">test</option>
            <option value="unassigned">unassigned</option>
          </select>
        </label>
        <label>Person
          <select value={person} onChange={(e) => setPerson(e.target.value)}>
            <option value="">all</option>
            {persons.map((p) => <option key={p} value={p}>{p}</option>)}
          </select>
        </label>
        <label className="toggle">
          <input type="checkbox" checked={unreviewed} onChange={() => setUnreviewed(!unreviewed)} />
          has unreviewed segments
        </label>
      </div>
      {user?.role !== "engineer" && (
        <form className="filters" aria-label="Import" ref={importForm}
          onSubmit={(e) => { e.preventDefault(); void importFile(e.currentTarget); }}>
          <label>Import a Vigil export
            <input type="file" name="file" accept=".json,.csv" />
          </label>
          <label>Format
            <select name="format" defaultValue="json">
              <option value="json">Vigil JSON (new video)</option>
              <option value="coco">COCO keypoints (new video)</option>
              <option value="csv">CSV labels (existing videos)</option>
            </select>
          </label>
          <label>Into
            <select name="mode" defaultValue="">
              <option value="">a new video (JSON, COCO) · merge (CSV)</option>
              <option value="merge">the existing video: add the labels it lacks</option>
              <option value="replace">the existing video: replace its imported labels under review</option>
            </select>
          </label>
          <button type="submit">Import</button>
          {imported && <span role="status">{imported}</span>}
        </form>
      )}
      {taken && (
        <div className="card confirm" role="dialog" aria-label="Video already labelled">
          <p>This video already has labels. Merge the imported labels with them, or replace them?</p>
          <p className="muted">
            {taken.video}: merge adds the labels it lacks; replace first withdraws its imported labels
            still under review.
          </p>
          <button type="button" className="primary" onClick={() => void sendImport({ ...taken, mode: "merge" })}>Merge</button>
          <button type="button" onClick={() => void sendImport({ ...taken, mode: "replace" })}>Replace</button>
          <button type="button" onClick={() => setTaken(null)}>Cancel</button>
        </div>
      )}
      {error && <p role="alert" className="error">{error}</p>}
      <div className="filters">
        <label>Search videos
          <input type="search" value={query} placeholder="name, person, location, status"
            onChange={(e) => { setQuery(e.target.value); setPage(0); }} />
        </label>
        <span className="muted" data-testid="video-count">{view.total} of {videos?.length ?? 0} videos</span>
      </div>
      {!videos ? <p className="muted">Loading…</p> : videos.length === 0 ? (
        <p className="empty">No videos match. Import some: <code>python -m backend.labelling.cli import-urfd</code></p>
      ) : (
        <table className="videos" aria-label="Videos">
          <thead>
            <tr>
              <th>Video</th><th>Mode</th><th>Split</th><th>Person</th><th>Location · camera</th>
              <th>Progress</th><th>Status</th><th>Unreviewed</th>
            </tr>
          </thead>
          <tbody>
            {view.rows.map((v) => {
              const share = v.frame_count ? v.labelled_frames / v.frame_count : 0;
              return (
                <tr key={v.id}>
                  <td>
                    <Link to={`/annotate/videos/${v.id}`}>{v.name}</Link>
                    {v.generated && <span className="tag">generated</span>}
                    {v.has_rgb && <span className="tag">RGB</span>}
                    {v.has_depth && <span className="tag">depth</span>}
                  </td>
                  <td>{v.mode}</td>
                  <td>
                    {user?.role === "admin" ? (
                      <select aria-label={`Split of ${v.name}`} value={v.split}
                        onChange={(e) => void changeSplit(v, e.target.value as Split)}>
                        <option value="train">train</option>
                        <option value="test">test</option>
                        <option value="unassigned">unassigned</option>
                      </select>
                    ) : v.split}
                  </td>
                  <td>{v.person ?? "–"}</td>
                  <td>{[v.location, v.camera].filter(Boolean).join(" · ") || "–"}</td>
                  <td>
                    <progress max={1} value={share} /> {Math.round(share * 100)}%
                    <span className="muted"> ({v.labelled_frames}/{v.frame_count})</span>
                  </td>
                  <td><span className={`vstatus vstatus-${v.status}`}>{v.status.replace("_", " ")}</span></td>
                  <td>{v.unreviewed || ""}</td>
                </tr>
              );
            })}
          </tbody>
        </table>
      )}
      {videos && view.pages > 1 && (
        <Pager label="Video pages" page={view.page} pages={view.pages} onPage={setPage} />
      )}
    </main>
  );
}
