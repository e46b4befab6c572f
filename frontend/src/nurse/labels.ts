import type { FalseAlarmReason, Verdict } from "../api/types";

export const VERDICT_LABEL: Record<Verdict, string> = {
  true_emergency: "True emergency",
  false_alarm: "False alarm",
  unsure: "Unsure",
};

export const REASON_LABEL: Record<FalseAlarmReason, string> = {
  bending: "Bending",
  sitting_down: "Sitting down",
  lying_down_deliberately: "Lying down deliberately",
  other: "Other",
};

export function verdictText(verdict: Verdict | null, reason: FalseAlarmReason | null): string {
  if (!verdict) return "–";
  return reason ? `${VERDICT_LABEL[verdict]} (${REASON_LABEL[reason].toLowerCase()})` : VERDICT_LABEL[verdict];
}
