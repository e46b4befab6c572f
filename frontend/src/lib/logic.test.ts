import { describe, expect, it } from "vitest";
import { reconnectDelayMs } from "./backoff";
import { bars, niceMax } from "./charts";
import { delayFilter, fitSkeletons, frameAt, type ReplayFrame } from "./replay";
import { homeFor, landingPage, mayOpen } from "./roles";
import { elapsed } from "./time";

const kp = (x: number, y: number) => Array.from({ length: 25 }, () => [x, y, 1]);
const frame = (ts: number, emergency: number): ReplayFrame => ({
  seq: Math.round(ts * 10),
  ts,
  keypoints: kp(ts, ts),
  decision: emergency >= 0.5 ? "emergency" : "normal",
  scores: { normal: 1 - emergency, emergency },
});

describe("delayFilter", () => {
  it("fires only after emergency held for the delay, and resets on interruption", () => {
    const frames = [0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6].map((ts, i) =>
      frame(ts, [0.2, 0.9, 0.9, 0.1, 0.8, 0.8, 0.8][i]),
    );
    const steps = delayFilter(frames, 0.5, 200);
    expect(steps.map((s) => s.state)).toEqual([
      "idle", "counting", "counting", "idle", "counting", "counting", "fired",
    ]);
    expect(steps[6].heldMs).toBe(200);
  });

  it("falls back to the frame decision without a threshold", () => {
    const steps = delayFilter([frame(0, 0.9)], null, 0);
    expect(steps[0].state).toBe("fired");
  });
});

describe("geometry", () => {
  it("fits every visible keypoint inside the canvas", () => {
    const frames = [frame(0, 0), { ...frame(1, 0), keypoints: kp(100, 300) }];
    const fit = fitSkeletons(frames, 200, 100, 10);
    for (const f of frames)
      for (const [x, y] of f.keypoints) {
        const px = x * fit.scale + fit.offsetX;
        const py = y * fit.scale + fit.offsetY;
        expect(px).toBeGreaterThanOrEqual(10 - 1e-9);
        expect(px).toBeLessThanOrEqual(190 + 1e-9);
        expect(py).toBeGreaterThanOrEqual(10 - 1e-9);
        expect(py).toBeLessThanOrEqual(90 + 1e-9);
      }
  });

  it("finds the nearest frame", () => {
    const frames = [0, 1, 2, 3].map((t) => frame(t, 0));
    expect(frameAt(frames, 1.4)).toBe(1);
    expect(frameAt(frames, 1.6)).toBe(2);
    expect(frameAt(frames, 99)).toBe(3);
    expect(frameAt([], 1)).toBe(-1);
  });

  it("scales bars to a nice maximum", () => {
    expect(niceMax(7)).toBe(10);
    expect(niceMax(0.3)).toBeCloseTo(0.5);
    const [a, b] = bars([{ key: "a", value: 5 }, { key: "b", value: 10 }], 100, 50);
    expect(a.height).toBeCloseTo(25);
    expect(b.y).toBeCloseTo(0);
  });
});

describe("small helpers", () => {
  it("formats elapsed time", () => {
    const t0 = "2026-01-01T10:00:00Z";
    const at = (s: number) => Date.parse(t0) + s * 1000;
    expect(elapsed(t0, at(8))).toBe("8 s");
    expect(elapsed(t0, at(245))).toBe("4 min 05 s");
    expect(elapsed(t0, at(7980))).toBe("2 h 13 min");
    expect(elapsed(t0, at(-5))).toBe("0 s");
  });

  it("backs off up to 8 s", () => {
    expect(reconnectDelayMs(0, () => 0)).toBe(500);
    expect(reconnectDelayMs(3, () => 0)).toBe(4000);
    expect(reconnectDelayMs(10, () => 1)).toBe(9600);
  });

  it("routes each role home and guards sections", () => {
    expect(homeFor("nurse")).toBe("/nurse");
    expect(homeFor("annotator")).toBe("/annotate");
    expect(mayOpen("nurse", "engineer")).toBe(false);
    expect(mayOpen("admin", "nurse")).toBe(true);
    expect(landingPage("nurse", "/nurse/alarms/7")).toBe("/nurse/alarms/7");
    expect(landingPage("annotator", "/nurse/alarms/7")).toBe("/annotate");
    expect(landingPage("nurse", "//evil.example/nurse")).toBe("/nurse");
    expect(landingPage("engineer", null)).toBe("/engineer");
  });
});
