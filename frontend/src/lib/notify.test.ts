import { describe, expect, it } from "vitest";
import { alarmNotice, newNotices } from "./notify";
import { testAlarm as alarm } from "./testAlarm";

describe("alarm notifications", () => {
  it("says kind, robot, patient and place; an Emergency stays until acted on", () => {
    const notice = alarmNotice(alarm({ id: 7, robot_id: "robot-a", patient: "P-17", location: "corridor B" }));
    expect(notice.title).toBe("Emergency – robot robot-a");
    expect(notice.options.body).toBe("patient P-17 at corridor B");
    expect(notice.options.requireInteraction).toBe(true);
    expect(notice.options.data).toEqual({ url: "/nurse/alarms/7" });
    expect(alarmNotice(alarm({ kind: "pause", priority: "medium" })).options.requireInteraction).toBe(false);
  });

  it("notifies each open alarm once, again when an Emergency escalates, never for acknowledged ones", () => {
    const seen = new Map<string, number>();
    const first = alarm({ id: 1, key: "r1/t1/emergency" });
    expect(newNotices([first], seen).map((a) => a.id)).toEqual([1]);
    expect(newNotices([first], seen)).toEqual([]);
    // Its stored version (same key) is not new.
    expect(newNotices([{ ...first, id: 2 }], seen)).toEqual([]);
    expect(newNotices([{ ...first, escalation_level: 1 }], seen).map((a) => a.id)).toEqual([1]);
    expect(newNotices([{ ...first, state: "missed", escalation_level: 2 }], seen)).toHaveLength(1);
    const acked = alarm({ id: 3, key: "r2/t2/emergency", state: "acknowledged" });
    expect(newNotices([acked], seen)).toEqual([]);
  });
});
