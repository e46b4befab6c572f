import { describe, expect, it } from "vitest";
import { testAlarm } from "../lib/testAlarm";
import { handoverSections, secondsText, shareText } from "./handoverLogic";

describe("shift handover", () => {
  it("groups rows open, missed, acknowledged, escalated, resolved and drops empty sections", () => {
    const rows = [
      { section: "resolved" as const, was_missed: true, alarm: testAlarm({ id: 1, state: "resolved", escalation_level: 3 }) },
      { section: "open" as const, was_missed: false, alarm: testAlarm({ id: 2 }) },
      { section: "missed" as const, was_missed: true, alarm: testAlarm({ id: 3, state: "missed", escalation_level: 3 }) },
    ];
    expect(handoverSections(rows).map((s) => [s.section, s.rows.map((r) => r.alarm.id)])).toEqual([
      ["open", [2]], ["missed", [3]], ["escalated", [1, 3]], ["resolved", [1]],
    ]);
  });

  it("words shares and seconds", () => {
    expect(shareText(0, 0)).toBe("no verdicts yet");
    expect(shareText(1, 4)).toBe("25 % (1 of 4 with a verdict)");
    expect(secondsText(null)).toBe("–");
    expect(secondsText(42.4)).toBe("42 s");
    expect(secondsText(125)).toBe("2 min 05 s");
    // Minutes and hours, never "133 min 00 s" nor "1 min 60 s".
    expect(secondsText(7980)).toBe("2 h 13 min");
    expect(secondsText(2972)).toBe("50 min");
    expect(secondsText(119.7)).toBe("2 min 00 s");
  });
});
