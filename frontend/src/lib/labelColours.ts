// The one source of label colours, used by every page and the legend: a class's colour family
// says how urgent it is. Emergency in the warm colours (red to orange), Pause between (amber),
// Normal in calm ones (teal to blue). Each fine label gets its own shade inside its class's
// family, so "Walking" is never red and "Lying on the floor" never green.

export type ClassName = "emergency" | "pause" | "normal";

/** The colour of each class (stripes, swatches, the legend). */
export const CLASS_COLOURS: Record<ClassName, string> = {
  emergency: "#dc2626",
  pause: "#d97706",
  normal: "#0d9488",
};

/** What is not (yet) a class: unlabelled, a placeholder. */
export const NO_CLASS_COLOUR = "#64748b";

/** The hue range (degrees, from → to, may wrap past 360) of each family. */
export const FAMILY_HUES: Record<ClassName, readonly [number, number]> = {
  emergency: [350, 20],
  pause: [30, 48],
  normal: [165, 225],
};

export const LEGEND: { cls: ClassName; name: string }[] = [
  { cls: "emergency", name: "Emergency" },
  { cls: "pause", name: "Pause" },
  { cls: "normal", name: "Normal" },
];

export function classColour(decision: string | null | undefined): string {
  return (decision && CLASS_COLOURS[decision as ClassName]) || NO_CLASS_COLOUR;
}

/** The family a hue belongs to, or null if it is in none. */
export function hueFamily(hue: number): ClassName | null {
  const h = ((hue % 360) + 360) % 360;
  for (const cls of Object.keys(FAMILY_HUES) as ClassName[]) {
    const [from, to] = FAMILY_HUES[cls];
    if (from <= to ? h >= from && h <= to : h >= from || h <= to) return cls;
  }
  return null;
}

/** One colour per fine label, inside its class's family: labels of one class are spread over
 * the family's hues and two lightnesses, so neighbours differ; dark enough for white text. */
export function labelColours(
  labels: readonly { key: string; decision: string | null | undefined }[],
): Map<string, string> {
  const byClass = new Map<string, string[]>();
  for (const l of labels) {
    const cls = l.decision && l.decision in FAMILY_HUES ? l.decision : "none";
    byClass.set(cls, [...(byClass.get(cls) ?? []), l.key]);
  }
  const colours = new Map<string, string>();
  for (const [cls, keys] of byClass) {
    keys.forEach((key, i) => {
      if (cls === "none") {
        colours.set(key, NO_CLASS_COLOUR);
        return;
      }
      const [from, to] = FAMILY_HUES[cls as ClassName];
      const span = (to - from + 360) % 360;
      const hue = (from + (keys.length > 1 ? (span * i) / (keys.length - 1) : span / 2)) % 360;
      const light = i % 2 === 0 ? 38 : 30;
      colours.set(key, `hsl(${hue.toFixed(1)}, 70%, ${light}%)`);
    });
  }
  return colours;
}

/** The hue of an `hsl(...)` colour made by labelColours. */
export function hueOf(colour: string): number {
  const m = colour.match(/^hsl\(([\d.]+)/);
  if (!m) throw new Error(`not an hsl colour: ${colour}`);
  return Number(m[1]);
}
