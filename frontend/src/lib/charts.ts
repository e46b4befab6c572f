// Minimal chart geometry for plain SVG charts.

/** A "nice" axis maximum: 1, 2 or 5 times a power of ten, at least the data maximum. */
export function niceMax(value: number): number {
  if (!(value > 0)) return 1;
  const power = 10 ** Math.floor(Math.log10(value));
  for (const step of [1, 2, 5, 10]) if (step * power >= value) return step * power;
  return 10 * power;
}

export function ticks(max: number, count = 4): number[] {
  return Array.from({ length: count + 1 }, (_, i) => (max * i) / count);
}

export interface Bar {
  key: string;
  x: number;
  width: number;
  y: number;
  height: number;
  value: number;
}

/** Vertical bars for values over a plot area of plotWidth x plotHeight (y grows downwards). */
export function bars(
  values: ReadonlyArray<{ key: string; value: number }>,
  plotWidth: number,
  plotHeight: number,
  max = niceMax(Math.max(0, ...values.map((v) => v.value))),
  gap = 0.2,
): Bar[] {
  const slot = values.length ? plotWidth / values.length : 0;
  return values.map(({ key, value }, i) => {
    const height = max > 0 ? (Math.max(0, value) / max) * plotHeight : 0;
    return {
      key,
      value,
      x: i * slot + (slot * gap) / 2,
      width: slot * (1 - gap),
      y: plotHeight - height,
      height,
    };
  });
}
