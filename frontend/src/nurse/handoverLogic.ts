// Shift handover: how its rows are grouped and its figures worded (plain functions, Vitest).
import type { components } from "../api/schema";
import { duration } from "../lib/time";

type Row = components["schemas"]["HandoverAlarm"];
type Section = Row["section"];

const SECTION_TITLES: Record<Section, string> = {
  open: "Open",
  missed: "Missed: needs review",
  acknowledged: "Acknowledged, not resolved",
  resolved: "Resolved this shift",
};
const ORDER: Section[] = ["open", "missed", "acknowledged", "resolved"];

/** Non-empty sections in handover order, rows as the server sent them (newest first); an
 * escalated alarm stays in its section and also shows under "Escalated". */
export function handoverSections(rows: Row[]): { section: Section | "escalated"; title: string; rows: Row[] }[] {
  const out: { section: Section | "escalated"; title: string; rows: Row[] }[] = ORDER.map((section) => ({
    section, title: SECTION_TITLES[section], rows: rows.filter((r) => r.section === section),
  }));
  out.splice(3, 0, { section: "escalated", title: "Escalated", rows: rows.filter((r) => r.alarm.escalation_level > 0) });
  return out.filter((s) => s.rows.length > 0);
}

export function shareText(part: number, whole: number): string {
  if (!whole) return "no verdicts yet";
  return `${Math.round((part / whole) * 100)} % (${part} of ${whole} with a verdict)`;
}

/** A figure in seconds in a nurse's words (minutes and hours: `duration`), "–" when absent. */
export function secondsText(value: number | null | undefined): string {
  return value == null ? "–" : duration(value);
}
