import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { coalesce } from "./coalesce";

describe("coalesce", () => {
  beforeEach(() => vi.useFakeTimers());
  afterEach(() => vi.useRealTimers());

  it("runs at once when idle, then once more at the end of the interval for a burst", () => {
    const run = vi.fn();
    const { trigger } = coalesce(run, 500);
    trigger();
    expect(run).toHaveBeenCalledTimes(1);
    for (let i = 0; i < 40; i++) trigger(); // a burst of pushes
    expect(run).toHaveBeenCalledTimes(1);
    vi.advanceTimersByTime(499);
    expect(run).toHaveBeenCalledTimes(1);
    vi.advanceTimersByTime(1);
    expect(run).toHaveBeenCalledTimes(2); // the trailing run: the last news is loaded
    vi.advanceTimersByTime(5_000);
    expect(run).toHaveBeenCalledTimes(2);
    trigger(); // idle for longer than the interval: at once again
    expect(run).toHaveBeenCalledTimes(3);
  });

  it("stop cancels a pending run", () => {
    const run = vi.fn();
    const { trigger, stop } = coalesce(run, 500);
    trigger();
    trigger();
    stop();
    vi.advanceTimersByTime(1_000);
    expect(run).toHaveBeenCalledTimes(1);
  });
});
