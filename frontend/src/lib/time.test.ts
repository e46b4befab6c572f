import { describe, expect, it } from "vitest";
import { duration } from "./time";

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
