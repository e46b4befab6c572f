import { useEffect, useState } from "react";
import { Link, useSearchParams } from "react-router-dom";
import { api, errorMessage } from "../../api/client";
import { metricName } from "../../lib/registry";
import { fmt, type Comparison, type GoldEvent } from "./types";

export function ComparePage() {
  const [params] = useSearchParams();
  const a = Number(params.get("a")), b = Number(params.get("b"));
  const [data, setData] = useState<Comparison | null>(null);
  const [error, setError] = useState<string | null>(null);
  useEffect(() => {
    void api.GET("/api/models/compare", { params: { query: { a, b } } }).then(({ data, error }) => {
      if (data) setData(data); else setError(errorMessage(error, "Could not compare"));
    });
  }, [a, b]);
  if (!data) return error ? <p role="alert" className="error">{error}</p> : <p className="muted">Loading…</p>;
  return (
    <>
      <h1>Compare</h1>
      <table className="table" aria-label="Comparison">
        <thead><tr><th>Metric</th>
          <th>A: <Link to={`/engineer/models/${data.a.id}`}>{data.a.version}</Link></th>
          <th>B: <Link to={`/engineer/models/${data.b.id}`}>{data.b.version}</Link></th><th>B − A</th></tr></thead>
        <tbody>{data.rows.map((r) => (
          <tr key={String(r.metric)} data-metric={String(r.metric)}>
            <td>{metricName(String(r.metric))}</td>
            <td className={r.winner === "a" ? "better" : ""}>{fmt(r.a)}</td>
            <td className={r.winner === "b" ? "better" : ""}>{fmt(r.b)}</td>
            <td>{fmt(r.delta)}</td>
          </tr>))}</tbody>
      </table>
      <h2>Per gold-set recording</h2>
      <table className="table" aria-label="Per recording">
        <thead><tr><th>Recording</th><th>A detected / alarms / time</th><th>B detected / alarms / time</th></tr></thead>
        <tbody>{data.events.map((row) => {
          const ea = row.a as GoldEvent | null, eb = row.b as GoldEvent | null;
          const cell = (e: GoldEvent | null) => e ? `${fmt(e.detected)} / ${e.alarms} / ${fmt(e.time_to_alarm_s, 2)}` : "–";
          return <tr key={String(row.sequence)}><td>{String(row.sequence)}</td><td>{cell(ea)}</td><td>{cell(eb)}</td></tr>;
        })}</tbody>
      </table>
    </>
  );
}
