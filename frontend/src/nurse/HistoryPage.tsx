import { useEffect, useState, type FormEvent } from "react";
import { Link, useNavigate } from "react-router-dom";
import { api, errorMessage } from "../api/client";
import type { Alarm, AlarmKind, Verdict } from "../api/types";
import { KIND_LABEL } from "../lib/alarmBoard";
import { clockTime, durationBetween, localInputToIso } from "../lib/time";
import { robotLabel } from "../lib/dispositions";
import { VERDICT_LABEL, verdictText } from "./labels";

interface Filters {
  ward: string;
  robot_id: string;
  kind: string;
  verdict: string;
  model_version: string;
  since: string;
  until: string;
}

const EMPTY: Filters = { ward: "", robot_id: "", kind: "", verdict: "", model_version: "", since: "", until: "" };
const PAGE = 50;

export function HistoryPage() {
  const [draft, setDraft] = useState<Filters>(EMPTY);
  const [filters, setFilters] = useState<Filters>(EMPTY);
  const [offset, setOffset] = useState(0);
  const [items, setItems] = useState<Alarm[]>([]);
  const [total, setTotal] = useState(0);
  const [error, setError] = useState<string | null>(null);
  const navigate = useNavigate();

  useEffect(() => {
    let live = true;
    const query = {
      ward: filters.ward || undefined,
      robot_id: filters.robot_id || undefined,
      kind: (filters.kind || undefined) as AlarmKind | undefined,
      verdict: (filters.verdict || undefined) as Verdict | undefined,
      model_version: filters.model_version || undefined,
      since: localInputToIso(filters.since),
      until: localInputToIso(filters.until),
      limit: PAGE,
      offset,
    };
    void api.GET("/api/alarm-history", { params: { query } }).then(({ data, error }) => {
      if (!live) return;
      if (data) { setItems(data.items); setTotal(data.total); setError(null); }
      else setError(errorMessage(error, "Could not load the alarm history"));
    });
    return () => { live = false; };
  }, [filters, offset]);

  function apply(event: FormEvent) {
    event.preventDefault();
    setOffset(0);
    setFilters(draft);
  }
  const field = (name: keyof Filters) => ({
    name,
    value: draft[name],
    onChange: (e: { target: { value: string } }) => setDraft({ ...draft, [name]: e.target.value }),
  });

  return (
    <main className="page">
      <h1>Alarm history</h1>
      <form className="filters" onSubmit={apply} aria-label="Filters">
        <label>Ward <input {...field("ward")} /></label>
        <label>Robot <input {...field("robot_id")} /></label>
        <label>Class
          <select {...field("kind")}>
            <option value="">any</option>
            {Object.entries(KIND_LABEL).map(([k, label]) => <option key={k} value={k}>{label}</option>)}
          </select>
        </label>
        <label>Verdict
          <select {...field("verdict")}>
            <option value="">any</option>
            {Object.entries(VERDICT_LABEL).map(([k, label]) => <option key={k} value={k}>{label}</option>)}
          </select>
        </label>
        <label>Model version <input {...field("model_version")} /></label>
        <label>From <input type="datetime-local" {...field("since")} /></label>
        <label>To <input type="datetime-local" {...field("until")} /></label>
        <button type="submit" className="primary">Search</button>
        <button type="button" onClick={() => { setDraft(EMPTY); setFilters(EMPTY); setOffset(0); }}>Clear</button>
      </form>
      {error && <p role="alert" className="error">{error}</p>}
      <p className="muted">{total} alarm{total === 1 ? "" : "s"}</p>
      <div className="table-wrap">
        <table className="table" aria-label="Alarms">
          <thead>
            <tr><th>#</th><th>Raised</th><th>Class</th><th>Ward</th><th>Robot</th><th>Patient</th>
              <th>State</th><th>Verdict</th><th>Model</th><th title="time to acknowledge">Ack</th></tr>
          </thead>
          <tbody>
            {items.map((a) => (
              <tr key={a.id} className="clickable" onClick={() => navigate(`/nurse/alarms/${a.id}`)}>
                <td><Link to={`/nurse/alarms/${a.id}`}>{a.id}</Link></td>
                <td>{clockTime(a.raised_at)}</td>
                <td><span className={`pill kind-${a.kind}`}>{KIND_LABEL[a.kind]}</span></td>
                <td>{a.ward ?? "–"}</td>
                <td>{robotLabel(a)}</td>
                <td>{a.patient ?? "–"}</td>
                <td>{a.state}</td>
                <td>{verdictText(a.verdict, a.reason)}</td>
                <td>{a.model_version ?? "–"}</td>
                <td data-testid="time-to-ack">{durationBetween(a.raised_at, a.acknowledged_at)}</td>
              </tr>
            ))}
          </tbody>
        </table>
      </div>
      <div className="pager">
        <button type="button" disabled={offset === 0} onClick={() => setOffset(Math.max(0, offset - PAGE))}>Newer</button>
        <button type="button" disabled={offset + PAGE >= total} onClick={() => setOffset(offset + PAGE)}>Older</button>
      </div>
    </main>
  );
}
