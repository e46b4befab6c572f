/** A plain table of whatever fields the rows have (for the minimal pages). */
export function DataTable({ rows, label }: { rows: ReadonlyArray<Record<string, unknown>>; label: string }) {
  if (rows.length === 0) return <p className="empty">None yet.</p>;
  const columns = Object.keys(rows[0]);
  const show = (v: unknown) => (v === null || v === undefined ? "–" : typeof v === "object" ? JSON.stringify(v) : String(v));
  return (
    <div className="table-wrap">
      <table className="table" aria-label={label}>
        <thead><tr>{columns.map((c) => <th key={c}>{c}</th>)}</tr></thead>
        <tbody>
          {rows.map((row, i) => (
            <tr key={i}>{columns.map((c) => <td key={c}>{show(row[c])}</td>)}</tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}
