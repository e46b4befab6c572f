import { describe, expect, it } from "vitest";
import {
  UndoStack,
  clampFrame,
  dragEdge,
  frameToX,
  inverse,
  labelColours,
  moveActive,
  nextSpeed,
  packSubRows,
  searchChoice,
  searchLabels,
  segmentAt,
  spanFromMarks,
  xToFrame,
  type Edit,
} from "./timelineLogic";

describe("frames and pixels", () => {
  it("maps frames to pixels and back to the same frame", () => {
    for (const frame of [0, 1, 79, 159]) {
      const x = frameToX(frame, 160, 800) + 0.5;
      expect(xToFrame(x, 160, 800)).toBe(frame);
    }
    expect(xToFrame(-20, 160, 800)).toBe(0);
    expect(xToFrame(5000, 160, 800)).toBe(159);
    expect(clampFrame(3.6, 160)).toBe(4);
  });

  it("builds a span from in and out points in either order", () => {
    expect(spanFromMarks(120, 95)).toEqual({ first_frame: 95, last_frame: 120 });
    expect(spanFromMarks(null, 95)).toBeNull();
  });

  it("drags an edge without inverting the span or leaving the video", () => {
    const span = { first_frame: 10, last_frame: 20 };
    expect(dragEdge(span, "first", 25, 160)).toEqual({ first_frame: 20, last_frame: 20 });
    expect(dragEdge(span, "last", 500, 160)).toEqual({ first_frame: 10, last_frame: 159 });
    expect(dragEdge(span, "first", 4, 160)).toEqual({ first_frame: 4, last_frame: 20 });
  });

  it("steps playback speed within 0.25x..4x", () => {
    expect(nextSpeed(4, 1)).toBe(4);
    expect(nextSpeed(0.25, -1)).toBe(0.25);
    expect(nextSpeed(1, 1)).toBe(2);
  });
});

describe("undo and redo", () => {
  const data = { first_frame: 95, last_frame: 104, label_key: "falling" };

  it("inverts each kind of edit", () => {
    const update: Edit = { kind: "update", id: 1, before: data, after: { ...data, last_frame: 110 } };
    expect(inverse(update)).toEqual({ kind: "update", id: 1, before: update.after, after: data });
    expect(inverse({ kind: "create", id: 2, data })).toEqual({ kind: "delete", id: 2, data });
    expect(inverse(inverse(update))).toEqual(update);
  });

  it("undoes in reverse order, redoes, and a new edit clears redo", () => {
    const stack = new UndoStack();
    stack.push({ kind: "create", id: 1, data });
    stack.push({ kind: "update", id: 1, before: data, after: { ...data, label_key: "impact" } });
    expect(stack.undo()).toMatchObject({ kind: "update", after: { label_key: "falling" } });
    expect(stack.undo()).toMatchObject({ kind: "delete", id: 1 });
    expect(stack.undo()).toBeNull();
    expect(stack.redo()).toMatchObject({ kind: "create", id: 1 });
    expect(stack.canRedo).toBe(true);
    stack.push({ kind: "delete", id: 1, data });
    expect(stack.canRedo).toBe(false);
  });

  it("follows a segment re-created under a new id", () => {
    const stack = new UndoStack();
    stack.push({ kind: "create", id: 7, data });
    stack.push({ kind: "update", id: 7, before: data, after: { ...data, first_frame: 90 } });
    stack.undo();
    stack.undo(); // deletes segment 7 on the server
    const redo = stack.redo(); // re-creates it: the server answers with id 12
    expect(redo?.id).toBe(7);
    stack.remap(7, 12);
    expect(stack.redo()).toMatchObject({ kind: "update", id: 12 });
  });

  it("rolls back the bookkeeping when the server refuses", () => {
    const stack = new UndoStack();
    stack.push({ kind: "create", id: 1, data });
    stack.undo();
    stack.rollback(true);
    expect(stack.canUndo).toBe(true);
    expect(stack.canRedo).toBe(false);
  });
});

describe("labels and segments", () => {
  const labels = [
    { key: "lying_on_floor", name: "Lying on the floor" },
    { key: "falling", name: "Falling" },
    { key: "falling_out_of_wheelchair", name: "Falling out of wheelchair" },
  ];

  it("finds labels by key or name, prefix matches first", () => {
    expect(searchLabels(labels, "fall").map((l) => l.key)).toEqual([
      "falling",
      "falling_out_of_wheelchair",
    ]);
    expect(searchLabels(labels, "floor")[0].key).toBe("lying_on_floor");
    expect(searchLabels(labels, "zzz")).toEqual([]);
  });

  it("picks the most specific segment under the playhead", () => {
    const segs = [
      { id: 1, first_frame: 0, last_frame: 159 },
      { id: 2, first_frame: 95, last_frame: 104 },
    ];
    expect(segmentAt(segs, 100)?.id).toBe(2);
    expect(segmentAt(segs, 10)?.id).toBe(1);
    expect(segmentAt(segs, 200)).toBeNull();
  });
});

describe("label search never guesses", () => {
  const labels = [
    { key: "lying_deliberately", name: "Lying down deliberately" },
    { key: "lying_on_floor", name: "Lying on the floor" },
    { key: "walking", name: "Walking" },
  ];

  it("applies nothing on Enter while several labels match and none is chosen", () => {
    const matches = searchLabels(labels, "lying");
    expect(matches).toHaveLength(2);
    expect(searchChoice(matches, null)).toBeNull();
  });

  it("applies the label the user moved to, or the only match", () => {
    const matches = searchLabels(labels, "lying");
    const second = moveActive(moveActive(null, 1, matches.length), 1, matches.length);
    expect(second).toBe(1);
    expect(searchChoice(matches, second)?.key).toBe("lying_on_floor");
    expect(searchChoice(searchLabels(labels, "walk"), null)?.key).toBe("walking");
    expect(searchChoice([], null)).toBeNull();
  });

  it("keeps the highlight inside the list", () => {
    expect(moveActive(null, -1, 3)).toBe(2);
    expect(moveActive(2, 1, 3)).toBe(2);
    expect(moveActive(0, -1, 3)).toBe(0);
    expect(moveActive(1, 1, 0)).toBeNull();
  });
});

describe("overlapping segments in one lane", () => {
  it("puts overlapping segments on different sub-rows and reuses free ones", () => {
    const segments = [
      { id: 1, first_frame: 83, last_frame: 159 },
      { id: 2, first_frame: 80, last_frame: 108 },
      { id: 3, first_frame: 0, last_frame: 79 },
      { id: 4, first_frame: 109, last_frame: 120 },
    ];
    const { subRow, count } = packSubRows(segments);
    expect(count).toBe(2);
    expect(subRow.get(1)).not.toBe(subRow.get(2));
    expect(subRow.get(3)).toBe(0);
    expect(subRow.get(4)).toBe(subRow.get(2));
    for (const a of segments)
      for (const b of segments)
        if (a.id < b.id && a.first_frame <= b.last_frame && b.first_frame <= a.last_frame)
          expect(subRow.get(a.id)).not.toBe(subRow.get(b.id));
  });

  it("keeps an empty lane one row high", () => {
    expect(packSubRows([]).count).toBe(1);
  });
});

describe("label colours", () => {
  it("gives every label of the taxonomy its own colour", () => {
    const classes = ["normal", "emergency", "pause"];
    const labels = Array.from({ length: 22 }, (_, i) => ({ key: `label_${i}`, decision: classes[i % 3] }));
    const colours = labelColours(labels);
    expect(new Set(colours.values()).size).toBe(22);
  });
});
