import { describe, expect, it } from "vitest";
import { CLASS_COLOURS, classColour, hueFamily, hueOf, labelColours } from "./labelColours";

// Fine labels of the default taxonomy (vigil/taxonomy.py) with their walking-mode class.
const WALKING = [
  { key: "walking", decision: "normal" },
  { key: "standing", decision: "normal" },
  { key: "sitting_chair", decision: "normal" },
  { key: "lying_bed", decision: "normal" },
  { key: "losing_balance", decision: "emergency" },
  { key: "falling", decision: "emergency" },
  { key: "lying_floor", decision: "emergency" },
  { key: "sitting_floor", decision: "emergency" },
];
const WHEELCHAIR = [
  { key: "sitting_wheelchair", decision: "normal" },
  { key: "leaning_forward", decision: "pause" },
  { key: "standing_up", decision: "pause" },
  { key: "slipping", decision: "emergency" },
];

function hexHue(hex: string): number {
  const [r, g, b] = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16) / 255);
  const max = Math.max(r, g, b);
  const d = max - Math.min(r, g, b);
  const h = max === r ? ((g - b) / d) % 6 : max === g ? (b - r) / d + 2 : (r - g) / d + 4;
  return (h * 60 + 360) % 360;
}

describe("label colours follow the class", () => {
  it("puts each fine label's colour in its class's family", () => {
    for (const labels of [WALKING, WHEELCHAIR]) {
      const colours = labelColours(labels);
      for (const l of labels) expect(hueFamily(hueOf(colours.get(l.key)!)), l.key).toBe(l.decision);
    }
  });

  it("never paints Walking red or Lying on the floor green", () => {
    const colours = labelColours(WALKING);
    expect(hueFamily(hueOf(colours.get("walking")!))).toBe("normal");
    expect(hueFamily(hueOf(colours.get("lying_floor")!))).toBe("emergency");
  });

  it("gives every label of one class its own colour", () => {
    const colours = labelColours(WALKING);
    expect(new Set(colours.values()).size).toBe(WALKING.length);
  });

  it("uses class colours of the same families (stripes, swatches, legend)", () => {
    for (const cls of ["emergency", "pause", "normal"] as const) {
      expect(hueFamily(hexHue(CLASS_COLOURS[cls]))).toBe(cls);
      expect(classColour(cls)).toBe(CLASS_COLOURS[cls]);
    }
  });
});
