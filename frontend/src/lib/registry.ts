// Registry wording and list handling for the engineer's pages (pure, tested in registry.test.ts).

export interface ModelReach {
  status: "candidate" | "approved" | "production" | "retired";
  robots_assigned: number;
  robots_in_fleet: number;
  canary_robot?: string | null;
}

/** A model's status in words that say where it runs: a model on one robot of three is not
 * "production" for the whole fleet. */
export function statusText(m: ModelReach): string {
  if (m.canary_robot) return `canary on ${m.canary_robot}`;
  if (m.status === "production") {
    if (m.robots_assigned === 0) return "production, on no robot";
    if (m.robots_in_fleet > 0 && m.robots_assigned >= m.robots_in_fleet) return "production on every robot";
    return `production on ${m.robots_assigned} of ${m.robots_in_fleet} robots`;
  }
  return m.status;
}

/** Metric keys of the evaluation, in the words of the reference paper's Table 3. */
export const METRIC_NAMES: Record<string, string> = {
  frame_recall: "Frame recall",
  frame_precision: "Frame precision",
  frame_f1: "Frame F1",
  fp: "False-positive frames",
  fp_d: "False-positive frames after the delay filter",
  fp_d_over_fp: "Share of false-positive frames left after the delay filter",
  fn: "False-negative frames",
  fn_d: "False-negative frames after the delay filter",
  fn_d_over_fn: "Share of false-negative frames after the delay filter",
  falls_detected: "Falls detected",
  falls_total: "Falls in the gold set",
  adl_false_alarms: "Daily activities with a false alarm",
  adl_total: "Daily activities in the gold set",
  median_time_to_alarm_s: "Median time to alarm (s)",
  max_time_to_alarm_s: "Longest time to alarm (s)",
  event_f1: "Event F1",
  threshold: "Threshold",
  delay_ms: "Delay (ms)",
};

export const metricName = (key: string): string => METRIC_NAMES[key] ?? key.replaceAll("_", " ");

/** The gate report's `split`: how the gold set a model was judged on relates to the recordings
 * it was trained on (`overlap` and `training_recordings` null: nothing records them). */
export interface GoldSplit {
  gold_recordings: number;
  training_recordings: number | null;
  overlap: string[] | null;
}

const recordings = (n: number): string => `${n} gold recording${n === 1 ? "" : "s"}`;

/** Where a model's gold-set figures come from, in words: from recordings it was not trained on,
 * or the reason the gate refuses them (the gold recordings it was trained on, by name; or no
 * record of its training recordings). */
export function goldSplitText(split: GoldSplit): { text: string; clean: boolean } {
  const n = split.gold_recordings;
  if (split.overlap === null) {
    return {
      text: `Judged on ${recordings(n)}, but its training recordings are unknown: these may be training figures, so the gate refuses it.`,
      clean: false,
    };
  }
  if (split.overlap.length > 0) {
    return {
      text: `Judged on ${recordings(n)}, ${split.overlap.length} of which it was trained on (${split.overlap.join(", ")}): training figures, so the gate refuses it.`,
      clean: false,
    };
  }
  return {
    text: `Judged on ${recordings(n)} it was not trained on (trained on ${split.training_recordings} other recordings).`,
    clean: true,
  };
}

export type SortDirection = "asc" | "desc";

/** Rows matching a free-text query (every word somewhere in the row's text), sorted by one
 * key, cut into pages. Page numbers are clamped so a shrinking list never shows an empty page. */
export function listView<T>(
  rows: readonly T[],
  text: (row: T) => string,
  query: string,
  sortKey: (row: T) => string | number,
  direction: SortDirection,
  page: number,
  pageSize: number,
): { rows: T[]; total: number; page: number; pages: number } {
  const words = query.toLowerCase().split(/\s+/).filter(Boolean);
  const hits = rows.filter((r) => {
    const haystack = text(r).toLowerCase();
    return words.every((w) => haystack.includes(w));
  });
  const sign = direction === "asc" ? 1 : -1;
  hits.sort((a, b) => {
    const x = sortKey(a), y = sortKey(b);
    return (x < y ? -1 : x > y ? 1 : 0) * sign;
  });
  const pages = Math.max(1, Math.ceil(hits.length / pageSize));
  const current = Math.min(Math.max(page, 0), pages - 1);
  return { rows: hits.slice(current * pageSize, (current + 1) * pageSize), total: hits.length, page: current, pages };
}

/** Job kinds whose result is a newly registered model version. */
const REGISTERING_KINDS = new Set(["retrain", "rethreshold", "register"]);

/** What a job's Result cell links to: the new version (jobs that register one) or the model a
 * what-if or evaluation ran on, named as such; null when the result names no model. */
export function jobResultLink(
  kind: string,
  result: Record<string, unknown> | null | undefined,
): { modelId: number; text: string } | null {
  const id = result?.model_version_id;
  if (typeof id !== "number") return null;
  const version = typeof result?.version === "string" ? result.version : null;
  if (REGISTERING_KINDS.has(kind)) return { modelId: id, text: version ?? "the new version" };
  return { modelId: id, text: `ran on model #${id}${version ? ` (${version})` : ""}` };
}
