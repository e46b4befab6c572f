// Names for the API shapes, all derived from the generated OpenAPI schema (npm run gen:api).
import type { components } from "./schema";

type Schemas = components["schemas"];

export type User = Schemas["UserOut"];
export type Role = User["role"];
export type TokenOut = Schemas["TokenOut"];
export type Alarm = Schemas["AlarmOut"];
export type AlarmKind = Alarm["kind"];
export type AlarmState = Alarm["state"];
export type Verdict = NonNullable<Alarm["verdict"]>;
export type FalseAlarmReason = NonNullable<Alarm["reason"]>;
export type AlarmEvent = Schemas["AlarmEventOut"];

/** Messages the backend pushes over /ws/browser: the alarm board's, and the fleet's news (these
 * robots' rows or the deployments changed: the fleet page reloads; engineers and admins only). */
export type BrowserMessage =
  | { type: "snapshot"; alarms: Alarm[] }
  | { type: "alarm"; alarm: Alarm }
  | { type: "fleet"; robots: string[] };
