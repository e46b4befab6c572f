import { describe, expect, it } from "vitest";
import { itemOffsets, visibleSlice } from "./listWindow";

describe("list window", () => {
  const offsets = itemOffsets([30, 50, 50, 50, 30, 50]); // 0 30 80 130 180 210 260

  it("sums heights into offsets and the total", () => {
    expect(offsets).toEqual([0, 30, 80, 130, 180, 210, 260]);
  });

  it("takes every item that overlaps the range, and no other", () => {
    expect(visibleSlice(offsets, 0, 30)).toEqual([0, 1]);
    expect(visibleSlice(offsets, 29, 31)).toEqual([0, 2]);
    expect(visibleSlice(offsets, 85, 140)).toEqual([2, 4]);
    expect(visibleSlice(offsets, 130, 180)).toEqual([3, 4]);
    expect(visibleSlice(offsets, 250, 1000)).toEqual([5, 6]);
  });

  it("clamps ranges outside the list", () => {
    expect(visibleSlice(offsets, -500, 10)).toEqual([0, 1]);
    expect(visibleSlice(offsets, -500, -10)).toEqual([0, 0]);
    expect(visibleSlice(offsets, 400, 900)).toEqual([6, 6]);
    expect(visibleSlice(itemOffsets([]), 0, 100)).toEqual([0, 0]);
  });

  it("matches a plain scan on a long list", () => {
    const heights = Array.from({ length: 800 }, (_, i) => (i % 37 === 0 ? 34 : 48));
    const long = itemOffsets(heights);
    for (const [top, bottom] of [[0, 768], [5000, 5768], [12345, 13000], [38000, 40000]]) {
      const expected = heights.map((_, i) => i).filter((i) => long[i + 1] > top && long[i] < bottom);
      const [first, last] = visibleSlice(long, top, bottom);
      expect([first, last]).toEqual(expected.length ? [expected[0], expected[expected.length - 1] + 1] : [first, first]);
    }
  });
});
