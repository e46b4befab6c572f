import { describe, expect, it } from "vitest";
import { formatBytes, growthLine, keptInWords } from "./storage";

describe("storage page logic", () => {
  it("says sizes in decimal units", () => {
    expect(formatBytes(0)).toBe("0 B");
    expect(formatBytes(999)).toBe("999 B");
    expect(formatBytes(1536)).toBe("1.5 kB");
    expect(formatBytes(306e6)).toBe("306 MB");
    expect(formatBytes(15e12)).toBe("15.0 TB");
    expect(formatBytes(null)).toBe("–");
  });

  it("draws growth from the first day at the bottom to the largest at the top", () => {
    const line = growthLine(
      [{ day: "a", cumulative_bytes: 0 }, { day: "b", cumulative_bytes: 50 }, { day: "c", cumulative_bytes: 100 }],
      200, 100,
    );
    expect(line).toBe("0.0,100.0 100.0,50.0 200.0,0.0");
    expect(growthLine([], 200, 100)).toBe("");
  });

  it("lists what a run kept by reason", () => {
    expect(keptInWords({ labelled: 40, alarm_window: 3 })).toBe("3 alarm window, 40 labelled");
    expect(keptInWords({})).toBe("nothing");
  });
});
