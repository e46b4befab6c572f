// An alarm as the API sends it, for the unit tests; `over` sets the fields a test is about.
import type { Alarm } from "../api/types";

export function testAlarm(over: Partial<Alarm>): Alarm {
  return {
    id: 1,
    kind: "emergency",
    priority: "high",
    state: "open",
    robot_id: "r1",
    ward: "A",
    transport_id: "t1",
    patient: "P-1",
    location: "corridor",
    raised_at: "2026-01-01T10:00:00Z",
    updated_at: "2026-01-01T10:00:00Z",
    acknowledged_at: null,
    acknowledged_by: null,
    resolved_at: null,
    resolved_by: null,
    verdict: null,
    reason: null,
    comment: null,
    escalation_level: 0,
    realarmed_at: null,
    video_id: 1,
    decision_count: 1,
    first_seq: 10,
    last_seq: 20,
    model_version: "m1",
    threshold: 0.5,
    delay_ms: 300,
    stored: true,
    key: "r1/t1/emergency",
    ...over,
  };
}
