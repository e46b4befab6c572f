// The live alarm board's state: every open or acknowledged alarm, kept from websocket messages.
import type { Alarm, BrowserMessage } from "../api/types";

export type Board = ReadonlyMap<number, Alarm>;

export const emptyBoard: Board = new Map();

/** A snapshot replaces the board (after every (re)connect); an alarm message updates one entry.
 *
 * Fail open: while storage is stalled the server pushes alarms marked `stored: false` (with a
 * provisional negative id). The stored alarm with the same `key` replaces such a card once
 * storage recovers, and a not-yet-stored alarm is not shown beside a stored live one of its key:
 * one card per alarm, never two. */
export function applyMessage(board: Board, message: BrowserMessage): Board {
  if (message.type === "snapshot") return snapshotBoard(message.alarms);
  if (message.type === "fleet") return board; // the fleet page's news: no alarm in it
  const alarm = message.alarm;
  const known = board.get(alarm.id);
  // Messages may overtake each other; never let an older version replace a newer one.
  if (known && Date.parse(known.updated_at) > Date.parse(alarm.updated_at)) return board;
  if (!isStored(alarm) && isLive(alarm)) {
    for (const other of board.values()) {
      if (isStored(other) && other.key === alarm.key && isLive(other)) return board; // already shown
    }
  }
  const next = new Map(board);
  if (isStored(alarm)) {
    for (const [id, other] of board) if (!isStored(other) && other.key === alarm.key) next.delete(id);
  }
  if (isLive(alarm)) next.set(alarm.id, alarm);
  else next.delete(alarm.id);
  return next;
}

/** The board of a snapshot, built in one pass (a snapshot holds hundreds of alarms): the same
 * rules as one message at a time (the newest version of an alarm; a not-yet-stored alarm only
 * when no stored live alarm has its key). */
function snapshotBoard(alarms: readonly Alarm[]): Board {
  const next = new Map<number, Alarm>();
  const storedKeys = new Set<string>();
  for (const alarm of alarms) {
    if (!isStored(alarm) || !isLive(alarm)) continue;
    const known = next.get(alarm.id);
    if (known && Date.parse(known.updated_at) > Date.parse(alarm.updated_at)) continue;
    next.set(alarm.id, alarm);
  }
  for (const alarm of next.values()) storedKeys.add(alarm.key);
  for (const alarm of alarms) {
    if (isStored(alarm) || !isLive(alarm) || storedKeys.has(alarm.key)) continue;
    const known = next.get(alarm.id);
    if (known && Date.parse(known.updated_at) > Date.parse(alarm.updated_at)) continue;
    next.set(alarm.id, alarm);
  }
  return next;
}

/** False while the alarm was pushed before storage could keep it (fail open). */
export function isStored(alarm: Alarm): boolean {
  return alarm.stored !== false;
}

/** On the board: open, "missed: needs review" (latched) or acknowledged; not resolved. */
export function isLive(alarm: Alarm): boolean {
  return alarm.state === "open" || alarm.state === "acknowledged" || alarm.state === "missed";
}

/** Re-alarmed: acknowledged, then not resolved in time, so it calls for attention again. */
export function isRealarmed(alarm: Alarm): boolean {
  return (
    alarm.state === "acknowledged" &&
    !!alarm.realarmed_at &&
    (!alarm.acknowledged_at || Date.parse(alarm.realarmed_at) >= Date.parse(alarm.acknowledged_at))
  );
}

/** Open or re-alarmed: the alarm wants a nurse now. */
export function needsAttention(alarm: Alarm): boolean {
  return alarm.state === "open" || isRealarmed(alarm);
}

/** The board's groups, in triage order: what needs a person now (unacknowledged, or
 * re-alarmed), then the latched "missed: needs review" Emergencies (kept apart so they never
 * bury a fresh alarm), then what someone has acknowledged. */
export type TriageGroup = "new" | "missed" | "acknowledged";
export const TRIAGE_GROUPS: readonly TriageGroup[] = ["new", "missed", "acknowledged"];
export const GROUP_LABEL: Record<TriageGroup, string> = {
  new: "Needs attention",
  missed: "Missed: needs review",
  acknowledged: "Acknowledged",
};

export function triageGroup(alarm: Alarm): TriageGroup {
  if (alarm.state === "missed") return "missed";
  return needsAttention(alarm) ? "new" : "acknowledged";
}

/** Within a group: Emergency, then technical alarms, then Pause. */
export function kindRank(alarm: Alarm): number {
  if (alarm.kind === "emergency") return 0;
  if (alarm.kind === "pause") return 2;
  return 1;
}

const GROUP_RANK: Record<TriageGroup, number> = { new: 0, missed: 1, acknowledged: 2 };

/** An alarm's place in triage order as numbers; alarm objects are never changed in place (an
 * update is a new object), so the key is computed once per version. */
const sortKeys = new WeakMap<Alarm, [number, number, number]>();
function sortKey(alarm: Alarm): [number, number, number] {
  let key = sortKeys.get(alarm);
  if (!key) {
    key = [GROUP_RANK[triageGroup(alarm)] * 3 + kindRank(alarm), -Date.parse(alarm.raised_at), -alarm.id];
    sortKeys.set(alarm, key);
  }
  return key;
}

/** Triage order: group (needs attention, missed, acknowledged), then Emergency before
 * technical before Pause, then newest first (the alarm raised a second ago is the first card). */
export function compareForBoard(a: Alarm, b: Alarm): number {
  const x = sortKey(a);
  const y = sortKey(b);
  return x[0] - y[0] || x[1] - y[1] || x[2] - y[2];
}

export function sortForBoard(alarms: Iterable<Alarm>): Alarm[] {
  return [...alarms].sort(compareForBoard);
}

/** How many alarms each group holds, and how many of each kind class. */
export interface BoardCounts {
  new: number;
  missed: number;
  acknowledged: number;
  emergency: number;
  technical: number;
  pause: number;
  total: number;
}

export function countBoard(alarms: Iterable<Alarm>): BoardCounts {
  const counts: BoardCounts = { new: 0, missed: 0, acknowledged: 0, emergency: 0, technical: 0, pause: 0, total: 0 };
  for (const a of alarms) {
    counts[triageGroup(a)] += 1;
    counts[styleOf(a)] += 1;
    counts.total += 1;
  }
  return counts;
}

export interface BoardFilter {
  ward: string | null;
  robot: string | null;
  group: TriageGroup | null;
}

/** The board's filters: ward, robot and group (null: all). What the server sends is already
 * confined to the nurse's ward (backend/wards.py); these only narrow it further. */
export function filterBoard(alarms: Iterable<Alarm>, filter: BoardFilter): Alarm[] {
  return [...alarms].filter(
    (a) =>
      (filter.ward === null || a.ward === filter.ward) &&
      (filter.robot === null || a.robot_id === filter.robot) &&
      (filter.group === null || triageGroup(a) === filter.group),
  );
}

export function robotsOf(alarms: Iterable<Alarm>): string[] {
  const robots = [...alarms].map((a) => a.robot_id).filter((id): id is string => id !== null);
  return [...new Set(robots)].sort();
}

/** The Acknowledge button's rule, the same on the board's cards, its list and the replay page:
 * open, or missed (a missed alarm is acknowledged the same way). */
export function mayAcknowledge(alarm: Alarm): boolean {
  return alarm.state === "open" || alarm.state === "missed";
}

/** An Emergency nobody has answered: open, re-alarmed, or latched "missed" (a fall nobody
 * answered is never quieter than one somebody answered). Tone, banner and audio pause all
 * follow this one rule. */
export function isUnansweredEmergency(alarm: Alarm): boolean {
  return alarm.kind === "emergency" && (needsAttention(alarm) || alarm.state === "missed");
}

export function unacknowledgedEmergencies(alarms: Iterable<Alarm>): Alarm[] {
  return [...alarms].filter(isUnansweredEmergency);
}

export interface EmergencyBannerState {
  /** The banner's alarm: the newest unanswered Emergency in triage order (a fresh one before a
   * missed one). */
  alarm: Alarm;
  /** How many more unanswered Emergencies wait beside it. */
  others: number;
  /** Of all unanswered Emergencies, how many are already missed. */
  missed: number;
  /** The one waiting longest. */
  oldest: Alarm;
}

/** The sticky banner: stays while any Emergency of the ward is unanswered, missed included,
 * naming how many, how many are missed and the oldest. */
export function bannerEmergency(alarms: Iterable<Alarm>): EmergencyBannerState | null {
  const waiting = unacknowledgedEmergencies(alarms);
  if (!waiting.length) return null;
  let newest = waiting[0];
  let oldest = waiting[0];
  let missed = 0;
  for (const a of waiting) {
    if (a.state === "missed") missed += 1;
    if (compareForBoard(a, newest) < 0) newest = a;
    if (Date.parse(a.raised_at) < Date.parse(oldest.raised_at)) oldest = a;
  }
  return { alarm: newest, others: waiting.length - 1, missed, oldest };
}

/** "transport ended 40 min ago", for an alarm whose transport is over (null while under way). */
export function transportEndedText(alarm: Alarm, nowMs: number): string | null {
  if (!alarm.transport_ended_at) return null;
  const minutes = Math.max(0, Math.floor((nowMs - Date.parse(alarm.transport_ended_at)) / 60_000));
  return minutes < 1 ? "transport ended just now" : `transport ended ${minutes} min ago`;
}

export function inWard(alarms: Iterable<Alarm>, ward: string | null): Alarm[] {
  return [...alarms].filter((a) => ward === null || a.ward === ward);
}

export function wardsOf(alarms: Iterable<Alarm>): string[] {
  const wards = new Set<string>();
  for (const a of alarms) if (a.ward) wards.add(a.ward);
  return [...wards].sort();
}

/** The emergency sound repeats while any emergency on the shown board is unanswered: open,
 * missed, or re-alarmed because it was acknowledged but not resolved in time. */
export function soundRequired(alarms: Iterable<Alarm>): boolean {
  for (const a of alarms) if (isUnansweredEmergency(a)) return true;
  return false;
}

export type AlarmStyle = "emergency" | "pause" | "technical";

export function styleOf(alarm: Alarm): AlarmStyle {
  if (alarm.kind === "emergency") return "emergency";
  if (alarm.kind === "pause") return "pause";
  return "technical";
}

export const KIND_LABEL: Record<Alarm["kind"], string> = {
  emergency: "Emergency",
  pause: "Pause",
  robot_offline: "Robot offline",
  stream_stalled: "Stream stalled",
  detection_degraded: "Detection degraded",
  storage_stalled: "Storage stalled",
  patient_not_seen: "Patient not in view",
  alarm_distribution_down: "Phones not reached (alarm distribution down)",
};

const INPUT_WORDS: Record<string, string> = { keypoints: "keypoints", depth: "depth", floor: "floor measures" };

/** What a technical alarm is about, in a line: "Detection degraded: no depth/floor measures,
 * running keypoints-only fallback gbt-kp-3" (from the alarm's details). */
export function alarmTitle(alarm: Alarm): string {
  const label = KIND_LABEL[alarm.kind];
  if (alarm.kind !== "detection_degraded") return label;
  const details = (alarm.details ?? {}) as Record<string, unknown>;
  const missing = Array.isArray(details.missing_inputs) ? (details.missing_inputs as string[]) : [];
  const running = typeof details.running_model === "string" ? details.running_model : null;
  const assigned = typeof details.assigned_model === "string" ? details.assigned_model : null;
  // Degraded with no input missing: the robot refused its model (its file is not the registry's).
  const what = missing.length ? `no ${missing.map((m) => INPUT_WORDS[m] ?? m).join("/")}`
    : assigned ? `model ${assigned} refused` : "an input is missing";
  const how = running && running !== assigned ? `running keypoints-only fallback ${running}`
    : running ? `${running} runs on what is left` : "no fallback model";
  return `${label}: ${what}, ${how}`;
}
