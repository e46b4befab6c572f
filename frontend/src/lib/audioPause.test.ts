import { describe, expect, it } from "vitest";
import { AUDIO_PAUSE_MS, pauseAudio, pauseHolds, pauseLeft } from "./audioPause";
import { testAlarm } from "./testAlarm";

const calling = testAlarm({ id: 1, key: "r1/t1/emergency" });
const now = Date.parse("2026-01-01T10:00:00Z");

describe("audio paused for 2 minutes", () => {
  it("holds while only the silenced Emergencies call, and runs out by itself", () => {
    const pause = pauseAudio([calling], now);
    expect(pauseHolds(pause, [calling], now + 60_000)).toBe(true);
    expect(pauseLeft(pause, now + 18_000)).toBe("1:42");
    expect(pauseHolds(pause, [calling], now + AUDIO_PAUSE_MS)).toBe(false);
  });

  it("lifts itself when a new Emergency arrives, but not for a Pause or a technical alarm", () => {
    const pause = pauseAudio([calling], now);
    const pauseKind = testAlarm({ id: 2, key: "r2/t2/pause", kind: "pause", priority: "medium" });
    expect(pauseHolds(pause, [calling, pauseKind], now + 1000)).toBe(true);
    const fresh = testAlarm({ id: 3, key: "r3/t3/emergency" });
    expect(pauseHolds(pause, [calling, fresh], now + 1000)).toBe(false);
  });

  it("keeps the silenced Emergency silent when its stored version replaces the provisional one", () => {
    const provisional = testAlarm({ id: -1, stored: false, key: "r1/t9/emergency" });
    const pause = pauseAudio([provisional], now);
    const stored = testAlarm({ id: 40, stored: true, key: "r1/t9/emergency" });
    expect(pauseHolds(pause, [stored], now + 1000)).toBe(true);
  });

  it("keeps holding when a silenced Emergency goes missed, and a missed one silenced stays counted", () => {
    const pause = pauseAudio([calling], now);
    expect(pauseHolds(pause, [{ ...calling, state: "missed" }], now + 1000)).toBe(true);
    const missedElsewhere = testAlarm({ id: 4, key: "r4/t4/emergency", state: "missed" });
    expect(pauseHolds(pause, [calling, missedElsewhere], now + 1000)).toBe(false);
    expect(pauseHolds(pauseAudio([calling, missedElsewhere], now), [calling, missedElsewhere], now + 1000)).toBe(true);
  });

  it("does not hold without a pause", () => {
    expect(pauseHolds(null, [calling], now)).toBe(false);
  });
});
