// Render only what is visible: a long list of fixed-height items (the nurse board's list view
// holds hundreds of alarms) drawn as the slice the window shows, plus some overscan.

/** Each item's top offset in px, and the list's total height (one more entry). */
export function itemOffsets(heights: readonly number[]): number[] {
  const offsets = new Array<number>(heights.length + 1);
  offsets[0] = 0;
  for (let i = 0; i < heights.length; i++) offsets[i + 1] = offsets[i] + heights[i];
  return offsets;
}

/** The items [first, last) that overlap the px range [top, bottom) of the list. */
export function visibleSlice(offsets: readonly number[], top: number, bottom: number): [number, number] {
  const count = offsets.length - 1;
  if (count <= 0 || bottom <= top) return [0, 0];
  // The first item whose bottom edge is below `top`; the first whose top edge is at `bottom` or below.
  const first = firstIndex(offsets, (o) => o > top, 1) - 1;
  const last = firstIndex(offsets, (o) => o >= bottom, 0);
  return [Math.max(0, Math.min(first, count)), Math.max(0, Math.min(last, count))];
}

/** The smallest i >= from with past(offsets[i]) (offsets.length if none): binary search
 * (offsets ascend, so `past` holds from some index on). */
function firstIndex(offsets: readonly number[], past: (offset: number) => boolean, from: number): number {
  let lo = from;
  let hi = offsets.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (past(offsets[mid])) hi = mid;
    else lo = mid + 1;
  }
  return lo;
}
