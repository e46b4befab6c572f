// Storage page logic: byte sizes in words and the growth chart's line.

/** 1536 -> "1.5 kB", 3.2e9 -> "3.2 GB" (decimal units, as disks are sold). */
export function formatBytes(bytes: number | null | undefined): string {
  if (bytes === null || bytes === undefined) return "–";
  const units = ["B", "kB", "MB", "GB", "TB", "PB"];
  let value = bytes;
  let unit = 0;
  while (Math.abs(value) >= 1000 && unit < units.length - 1) {
    value /= 1000;
    unit += 1;
  }
  return unit === 0 ? `${value} B` : `${value.toFixed(value >= 100 ? 0 : 1)} ${units[unit]}`;
}

export interface GrowthPoint {
  day: string;
  cumulative_bytes: number;
}

/** SVG polyline points of cumulative bytes per day over a width x height area (y down). */
export function growthLine(points: ReadonlyArray<GrowthPoint>, width: number, height: number): string {
  if (points.length === 0) return "";
  const max = Math.max(1, ...points.map((p) => p.cumulative_bytes));
  const step = points.length > 1 ? width / (points.length - 1) : 0;
  return points
    .map((p, i) => `${(i * step).toFixed(1)},${(height - (p.cumulative_bytes / max) * height).toFixed(1)}`)
    .join(" ");
}

/** "3 alarm_window, 40 labelled" from a run's kept-by-reason counts. */
export function keptInWords(kept: Record<string, number> | null | undefined): string {
  const parts = Object.entries(kept ?? {})
    .sort(([a], [b]) => a.localeCompare(b))
    .map(([reason, n]) => `${n.toLocaleString("en")} ${reason.replace("_", " ")}`);
  return parts.length ? parts.join(", ") : "nothing";
}
