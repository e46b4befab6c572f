// Shapes of the registry API (from the generated OpenAPI schema) plus the untyped JSON parts.
import type { components } from "../../api/schema";
import type { GoldSplit } from "../../lib/registry";

type Schemas = components["schemas"];
export type ModelSummary = Schemas["ModelSummary"];
export type ModelDetail = Schemas["ModelDetail"];
export type Comparison = Schemas["Comparison"];
export type Deployment = Schemas["DeploymentOut"];
export type FleetRobot = Schemas["FleetRobot"];
export type Job = Schemas["JobOut"];
export type JobDetail = Schemas["JobDetail"];
export type JobKind = Job["kind"];

export interface GateCheck {
  name: string;
  passed: boolean;
  value: number | null;
  limit: number | null;
  detail: string;
}

export interface GateReport {
  model_version: string;
  passed: boolean;
  checks: GateCheck[];
  warnings?: string[];
  split?: GoldSplit | null;
}

export interface GoldEvent {
  sequence: string;
  kind: "fall" | "adl";
  alarms: number;
  detected: boolean | null;
  false_alarm: boolean;
  time_to_alarm_s: number | null;
}

export const fmt = (v: unknown, digits = 3): string => {
  if (v === null || v === undefined) return "–";
  if (typeof v === "number") return Number.isInteger(v) ? String(v) : v.toFixed(digits);
  if (typeof v === "boolean") return v ? "yes" : "no";
  return typeof v === "object" ? JSON.stringify(v) : String(v);
};
