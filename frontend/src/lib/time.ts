/** "8 s", "4 min 05 s", "2 h 13 min": time elapsed since an ISO timestamp. */
export function elapsed(sinceIso: string, nowMs: number): string {
  const seconds = Math.max(0, Math.floor((nowMs - Date.parse(sinceIso)) / 1000));
  if (seconds < 60) return `${seconds} s`;
  const minutes = Math.floor(seconds / 60);
  if (minutes < 60) return `${minutes} min ${String(seconds % 60).padStart(2, "0")} s`;
  const hours = Math.floor(minutes / 60);
  return `${hours} h ${String(minutes % 60).padStart(2, "0")} min`;
}

export function clockTime(iso: string | null | undefined): string {
  if (!iso) return "–";
  return new Date(iso).toLocaleString(undefined, {
    dateStyle: "short",
    timeStyle: "medium",
  });
}

/** Value for an <input type="datetime-local"> -> ISO string (or undefined when empty). */
export function localInputToIso(value: string): string | undefined {
  if (!value) return undefined;
  const ms = Date.parse(value);
  return Number.isNaN(ms) ? undefined : new Date(ms).toISOString();
}

/** A duration in seconds as a person reads it: "0.4 s", "12 s", "4 min 05 s", "50 min",
 * "2 h 13 min" (the fatigue figures: not "2972 s"). */
export function duration(seconds: number): string {
  if (seconds < 1) return `${seconds.toFixed(1)} s`;
  if (seconds < 60) return `${Math.round(seconds)} s`;
  const total = Math.round(seconds);
  if (total < 600) return `${Math.floor(total / 60)} min ${String(total % 60).padStart(2, "0")} s`;
  const minutes = Math.round(seconds / 60);
  if (minutes < 60) return `${minutes} min`;
  return `${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

/** The time from one ISO timestamp to a later one, as `duration` says it ("4 min 05 s",
 * "50 min"), or "–" while there is no end yet (the history's time to acknowledge). */
export function durationBetween(startIso: string, endIso: string | null | undefined): string {
  if (!endIso) return "–";
  return duration(Math.max(0, (Date.parse(endIso) - Date.parse(startIso)) / 1000));
}
