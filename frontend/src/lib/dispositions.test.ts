import { describe, expect, it } from "vitest";
import { dispositionLine, rejectedOnPhone, robotLabel } from "./dispositions";

const at = (s: string) => `2026-01-01T12:03:${s}Z`;

describe("what the phones reported", () => {
  it("is nothing before anything came back", () => {
    expect(dispositionLine({ dispositions: [] })).toBeNull();
    expect(dispositionLine({})).toBeNull();
  });

  it("says delivered, read and accepted in order, naming the phone and the clinician", () => {
    const line = dispositionLine({
      dispositions: [
        { disposition: "delivered", clinician: "Anna Berg", device: "Anna's phone", at: at("05") },
        { disposition: "read", clinician: "Anna Berg", device: "Anna's phone", at: at("10") },
        { disposition: "accepted", clinician: "Anna Berg", device: "Anna's phone", at: at("20") },
      ],
    });
    expect(line).toMatch(/^Delivered to Anna's phone .*\d\d:\d\d:05.*, read by Anna Berg .*, accepted by Anna Berg .*20/);
  });

  it("flags an alarm whose last report is a rejection", () => {
    const delivered = { disposition: "delivered", clinician: "A B", device: "A's phone", at: at("05") };
    const rejected = { ...delivered, disposition: "rejected", at: at("09") };
    expect(rejectedOnPhone({ dispositions: [delivered] })).toBe(false);
    expect(rejectedOnPhone({ dispositions: [delivered, rejected] })).toBe(true);
  });

  it("names an alarm about no robot as the ward's", () => {
    expect(robotLabel({ robot_id: "robot-a" })).toBe("robot-a");
    expect(robotLabel({ robot_id: null })).toMatch(/ward/);
  });
});
