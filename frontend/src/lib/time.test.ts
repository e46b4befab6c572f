import { describe, expect, it } from "vitest";
import { duration, durationBetween } from "./time";

describe("durations in minutes and hours", () => {
  it("says seconds only below a minute", () => {
    expect(duration(0.42)).toBe("0.4 s");
    expect(duration(12.4)).toBe("12 s");
  });
  it("says minutes and hours above", () => {
    expect(duration(245)).toBe("4 min 05 s");
    expect(duration(2972)).toBe("50 min");
    expect(duration(7980)).toBe("2 h 13 min");
    expect(duration(3599.9)).toBe("1 h 00 min");
  });
});

describe("the time between two moments (the history's time to acknowledge)", () => {
  it("says it as a duration, not in raw seconds", () => {
    expect(durationBetween("2026-01-01T10:00:00Z", "2026-01-01T10:49:32Z")).toBe("50 min");
    expect(durationBetween("2026-01-01T10:00:00Z", "2026-01-01T10:04:05Z")).toBe("4 min 05 s");
    expect(durationBetween("2026-01-01T10:00:00Z", "2026-01-01T12:13:00Z")).toBe("2 h 13 min");
    expect(durationBetween("2026-01-01T10:00:00Z", "2026-01-01T10:00:12.400Z")).toBe("12 s");
  });
  it("says nothing while not acknowledged", () => {
    expect(durationBetween("2026-01-01T10:00:00Z", null)).toBe("–");
    expect(durationBetween("2026-01-01T10:00:00Z", undefined)).toBe("–");
  });
});
