import { describe, expect, it } from "vitest";
import { robotStateText, ROBOT_STATE_WORDS } from "./robotState";

describe("what the robot did", () => {
  it("says it in a nurse's words, with when", () => {
    expect(robotStateText(null, null)).toBeNull();
    expect(robotStateText("paused", null)).toBe("Robot paused");
    const text = robotStateText("emergency_stop", "2026-01-01T10:00:05Z");
    expect(text).toMatch(/^Robot stopped, waiting for help since .*\d\d:\d\d:\d\d/);
  });

  it("has words for every state and no engineer names in them", () => {
    for (const words of Object.values(ROBOT_STATE_WORDS)) expect(words).not.toMatch(/_/);
  });
});
