import { describe, expect, it } from "vitest";
import {
  alarmTitle,
  styleOf,
  applyMessage,
  bannerEmergency,
  countBoard,
  emptyBoard,
  filterBoard,
  inWard,
  isLive,
  isRealarmed,
  robotsOf,
  transportEndedText,
  triageGroup,
  soundRequired,
  unacknowledgedEmergencies,
  sortForBoard,
  wardsOf,
} from "./alarmBoard";
import { testAlarm as alarm } from "./testAlarm";

describe("applyMessage", () => {
  it("a snapshot replaces the board and drops resolved alarms", () => {
    const before = applyMessage(emptyBoard, { type: "alarm", alarm: alarm({ id: 9 }) });
    const after = applyMessage(before, {
      type: "snapshot",
      alarms: [alarm({ id: 1 }), alarm({ id: 2, state: "resolved" })],
    });
    expect([...after.keys()]).toEqual([1]);
  });

  it("updates, then removes an alarm once resolved", () => {
    let board = applyMessage(emptyBoard, { type: "snapshot", alarms: [alarm({ id: 3 })] });
    board = applyMessage(board, {
      type: "alarm",
      alarm: alarm({ id: 3, state: "acknowledged", updated_at: "2026-01-01T10:00:05Z" }),
    });
    expect(board.get(3)?.state).toBe("acknowledged");
    board = applyMessage(board, {
      type: "alarm",
      alarm: alarm({ id: 3, state: "resolved", updated_at: "2026-01-01T10:00:09Z" }),
    });
    expect(board.has(3)).toBe(false);
  });

  it("ignores an older version arriving after a newer one", () => {
    let board = applyMessage(emptyBoard, {
      type: "alarm",
      alarm: alarm({ id: 4, state: "acknowledged", updated_at: "2026-01-01T10:00:05Z" }),
    });
    board = applyMessage(board, { type: "alarm", alarm: alarm({ id: 4, state: "open" }) });
    expect(board.get(4)?.state).toBe("acknowledged");
  });

  it("leaves the board as it is on the fleet's news (an engineer's board gets it too)", () => {
    const board = applyMessage(emptyBoard, { type: "snapshot", alarms: [alarm({ id: 5 })] });
    expect(applyMessage(board, { type: "fleet", robots: ["robot-a"] })).toBe(board);
  });
});

describe("alarms pushed before they are stored (fail open)", () => {
  const unstored = alarm({ id: -1, stored: false, video_id: null });

  it("shows a not-yet-stored alarm, then the stored one replaces it: one card", () => {
    let board = applyMessage(emptyBoard, { type: "alarm", alarm: unstored });
    expect([...board.keys()]).toEqual([-1]);
    board = applyMessage(board, { type: "alarm", alarm: alarm({ id: 7, updated_at: "2026-01-01T10:00:03Z" }) });
    expect([...board.keys()]).toEqual([7]);
    expect(board.get(7)?.stored).toBe(true);
  });

  it("does not add a not-yet-stored card beside the stored live alarm of its key", () => {
    let board = applyMessage(emptyBoard, { type: "alarm", alarm: alarm({ id: 7 }) });
    board = applyMessage(board, { type: "alarm", alarm: { ...unstored, id: -2 } });
    expect([...board.keys()]).toEqual([7]);
    // Another transport's Emergency is another alarm.
    board = applyMessage(board, { type: "alarm", alarm: { ...unstored, id: -3, key: "r1/t2/emergency" } });
    expect([...board.keys()].sort()).toEqual([-3, 7]);
  });

  it("keeps an unrelated not-yet-stored card when a stored alarm of another key arrives", () => {
    let board = applyMessage(emptyBoard, { type: "alarm", alarm: unstored });
    board = applyMessage(board, { type: "alarm", alarm: alarm({ id: 8, key: "r2/t9/emergency" }) });
    expect([...board.keys()].sort()).toEqual([-1, 8]);
  });

  it("a snapshot builds the same board as its alarms sent one by one", () => {
    const alarms = Array.from({ length: 60 }, (_, i) =>
      alarm({
        id: i % 7 === 0 ? -i - 1 : i + 1,
        stored: i % 7 !== 0,
        key: `r${i % 5}/t${i % 11}/emergency`,
        state: i % 9 === 0 ? "resolved" : i % 4 === 0 ? "missed" : "open",
        updated_at: `2026-01-01T10:00:${String(i % 60).padStart(2, "0")}Z`,
      }),
    );
    let oneByOne = emptyBoard;
    for (const a of alarms.filter((x) => x.stored !== false)) oneByOne = applyMessage(oneByOne, { type: "alarm", alarm: a });
    for (const a of alarms.filter((x) => x.stored === false)) oneByOne = applyMessage(oneByOne, { type: "alarm", alarm: a });
    const snapshot = applyMessage(emptyBoard, { type: "snapshot", alarms });
    expect([...snapshot.keys()].sort((a, b) => a - b)).toEqual([...oneByOne.keys()].sort((a, b) => a - b));
    expect(snapshot.size).toBeGreaterThan(30);
  });

  it("a snapshot holding both keeps only the stored alarm", () => {
    const board = applyMessage(emptyBoard, { type: "snapshot", alarms: [unstored, alarm({ id: 9 })] });
    expect([...board.keys()]).toEqual([9]);
  });

  it("shows the storage-stalled technical alarm until it is pushed resolved", () => {
    const stalled = alarm({
      id: -5, kind: "storage_stalled", priority: "technical", stored: false, transport_id: null,
      key: "r1//storage_stalled", details: { summary: "frame writes blocked for over 2 s" },
    });
    let board = applyMessage(emptyBoard, { type: "alarm", alarm: stalled });
    expect(board.has(-5)).toBe(true);
    expect(alarmTitle(stalled)).toBe("Storage stalled");
    board = applyMessage(board, {
      type: "alarm",
      alarm: { ...stalled, state: "resolved", updated_at: "2026-01-01T10:00:09Z" },
    });
    expect(board.size).toBe(0);
  });
});

describe("board ordering and sound", () => {
  it("puts unacknowledged first, then Emergency, technical, Pause, then the newest", () => {
    const alarms = [
      alarm({ id: 1, state: "acknowledged" }),
      alarm({ id: 2, kind: "robot_offline", priority: "technical" }),
      alarm({ id: 3, kind: "pause", priority: "medium" }),
      alarm({ id: 4, raised_at: "2026-01-01T10:00:03Z" }),
      alarm({ id: 5, raised_at: "2026-01-01T09:59:00Z" }),
    ];
    expect(sortForBoard(alarms).map((a) => a.id)).toEqual([4, 5, 2, 3, 1]);
  });

  it("keeps missed Emergencies in a group of their own, after fresh alarms, before acknowledged ones", () => {
    const alarms = [
      alarm({ id: 1, state: "acknowledged", raised_at: "2026-01-01T10:09:00Z" }),
      alarm({ id: 2, state: "missed", escalation_level: 3, raised_at: "2026-01-01T09:00:00Z" }),
      alarm({ id: 3, state: "missed", escalation_level: 3, raised_at: "2026-01-01T09:30:00Z" }),
      alarm({ id: 4, kind: "pause", priority: "medium", raised_at: "2026-01-01T08:00:00Z" }),
      alarm({ id: 5, kind: "pause", priority: "medium", state: "acknowledged", raised_at: "2026-01-01T10:10:00Z" }),
      alarm({ id: 6, kind: "stream_stalled", priority: "technical", state: "acknowledged" }),
    ];
    const sorted = sortForBoard(alarms);
    expect(sorted.map((a) => a.id)).toEqual([4, 3, 2, 1, 6, 5]);
    expect(sorted.map(triageGroup)).toEqual(["new", "missed", "missed", "acknowledged", "acknowledged", "acknowledged"]);
    // A missed Emergency is latched on the board and, unanswered, keeps the tone repeating.
    expect(isLive(alarms[1])).toBe(true);
    expect(soundRequired([alarms[1]])).toBe(true);
    expect(countBoard(alarms)).toEqual({ new: 1, missed: 2, acknowledged: 3, emergency: 3, technical: 1, pause: 2, total: 6 });
  });

  it("a new alarm goes to the top of 500 older ones", () => {
    const old = Array.from({ length: 500 }, (_, i) =>
      alarm({ id: i + 1, raised_at: new Date(Date.parse("2026-01-01T08:00:00Z") + i * 1000).toISOString() }));
    const fresh = alarm({ id: 501, raised_at: "2026-01-01T10:00:00Z" });
    expect(sortForBoard([...old, fresh])[0].id).toBe(501);
    expect(sortForBoard(old)[0].id).toBe(500);
  });

  it("filters by ward, robot and group; lists the robots", () => {
    const alarms = [
      alarm({ id: 1, robot_id: "r2" }),
      alarm({ id: 2, robot_id: "r1", state: "missed" }),
      alarm({ id: 3, robot_id: "r1", ward: "B" }),
    ];
    expect(robotsOf(alarms)).toEqual(["r1", "r2"]);
    expect(filterBoard(alarms, { ward: null, robot: "r1", group: null }).map((a) => a.id)).toEqual([2, 3]);
    expect(filterBoard(alarms, { ward: "A", robot: "r1", group: null }).map((a) => a.id)).toEqual([2]);
    expect(filterBoard(alarms, { ward: null, robot: null, group: "missed" }).map((a) => a.id)).toEqual([2]);
    expect(filterBoard(alarms, { ward: null, robot: null, group: null })).toHaveLength(3);
  });

  it("announces the newest unacknowledged Emergency in the banner, not a missed or acknowledged one", () => {
    expect(bannerEmergency([alarm({ kind: "pause" }), alarm({ state: "acknowledged" })])).toBeNull();
    const banner = bannerEmergency([
      alarm({ id: 1, raised_at: "2026-01-01T10:00:00Z" }),
      alarm({ id: 2, raised_at: "2026-01-01T10:05:00Z", patient: "P-9" }),
      alarm({ id: 3, state: "acknowledged", raised_at: "2026-01-01T10:09:00Z" }),
    ]);
    expect(banner?.alarm.id).toBe(2);
    expect(banner?.others).toBe(1);
    expect(banner?.oldest.id).toBe(1);
    expect(banner?.missed).toBe(0);
  });

  it("never goes quieter for a missed Emergency: acknowledging the new ones keeps tone and banner", () => {
    const missed = [
      alarm({ id: 1, state: "missed", raised_at: "2026-01-01T09:00:00Z" }),
      alarm({ id: 2, state: "missed", raised_at: "2026-01-01T09:30:00Z" }),
    ];
    const fresh = alarm({ id: 3, raised_at: "2026-01-01T10:00:00Z" });
    expect(unacknowledgedEmergencies([...missed, fresh]).map((a) => a.id)).toEqual([1, 2, 3]);
    const before = bannerEmergency([...missed, fresh]);
    expect(before?.alarm.id).toBe(3);
    expect(before).toMatchObject({ others: 2, missed: 2 });
    // The nurse acknowledges the fresh one: the two missed ones still sound and keep the banner.
    const answered = { ...fresh, state: "acknowledged" as const, acknowledged_at: "2026-01-01T10:01:00Z" };
    expect(soundRequired([...missed, answered])).toBe(true);
    const after = bannerEmergency([...missed, answered]);
    expect(after?.alarm.id).toBe(2);
    expect(after).toMatchObject({ others: 1, missed: 2 });
    expect(after?.oldest.id).toBe(1);
    // Only when every Emergency is answered do tone and banner go.
    const allAnswered = missed.map((a) => ({ ...a, state: "acknowledged" as const }));
    expect(soundRequired([...allAnswered, answered])).toBe(false);
    expect(bannerEmergency([...allAnswered, answered])).toBeNull();
  });

  it("says when the transport of an alarm ended", () => {
    const now = Date.parse("2026-01-01T11:00:00Z");
    expect(transportEndedText(alarm({}), now)).toBeNull();
    expect(transportEndedText(alarm({ transport_ended_at: "2026-01-01T10:20:00Z" }), now)).toBe("transport ended 40 min ago");
    expect(transportEndedText(alarm({ transport_ended_at: "2026-01-01T10:59:40Z" }), now)).toBe("transport ended just now");
  });

  it("sounds again for an acknowledged emergency that re-alarmed", () => {
    const acked = alarm({ state: "acknowledged", acknowledged_at: "2026-01-01T10:00:10Z" });
    expect(soundRequired([acked])).toBe(false);
    const realarmed = { ...acked, realarmed_at: "2026-01-01T10:15:10Z" };
    expect(isRealarmed(realarmed)).toBe(true);
    expect(soundRequired([realarmed])).toBe(true);
    expect(sortForBoard([alarm({ id: 2, kind: "pause", priority: "medium" }), { ...realarmed, id: 1 }])
      .map((a) => a.id)).toEqual([1, 2]);
  });

  it("needs sound only for an unacknowledged emergency", () => {
    expect(soundRequired([alarm({ state: "acknowledged" }), alarm({ kind: "pause" })])).toBe(false);
    expect(soundRequired([alarm({ kind: "pause" }), alarm({})])).toBe(true);
  });

  it("filters by ward and lists wards", () => {
    const alarms = [alarm({ id: 1, ward: "B" }), alarm({ id: 2, ward: "A" }), alarm({ id: 3, ward: "" })];
    expect(wardsOf(alarms)).toEqual(["A", "B"]);
    expect(inWard(alarms, "B").map((a) => a.id)).toEqual([1]);
    expect(inWard(alarms, null)).toHaveLength(3);
  });
});

describe("alarm titles", () => {
  it("says what a degraded detection lacks and what runs instead", () => {
    const degraded = alarm({
      kind: "detection_degraded",
      priority: "technical",
      details: { missing_inputs: ["depth", "floor"], assigned_model: "gbt-floor-2", running_model: "gbt-kp-3" },
    });
    expect(alarmTitle(degraded)).toBe("Detection degraded: no depth/floor measures, running keypoints-only fallback gbt-kp-3");
    const noFallback = alarm({ kind: "detection_degraded", priority: "technical", details: { missing_inputs: ["floor"], assigned_model: "m", running_model: null } });
    expect(alarmTitle(noFallback)).toBe("Detection degraded: no floor measures, no fallback model");
    const refused = alarm({ kind: "detection_degraded", priority: "technical", details: { missing_inputs: [], assigned_model: "rf-7", running_model: "kp-2" } });
    expect(alarmTitle(refused)).toBe("Detection degraded: model rf-7 refused, running keypoints-only fallback kp-2");
    expect(alarmTitle(alarm({ kind: "robot_offline", priority: "technical" }))).toBe("Robot offline");
    const lost = alarm({ kind: "patient_not_seen", priority: "technical" });
    expect(alarmTitle(lost)).toBe("Patient not in view");
    expect(styleOf(lost)).toBe("technical");
  });
});
