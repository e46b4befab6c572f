"""Choose the operating point on training predictions only: threshold, then delay by F1."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vigil.classes import Decision
from vigil.events import (
    DELAY_GRID_S,
    SequenceEvent,
    alarm_times_over_delays,
    event_f1,
    summarise,
)
from vigil.policy import TIME_EPSILON, alarm_mask, apply_delay, raw_decisions
from vigil.thresholds import f1_from_counts, override_threshold, youden_threshold
from worker.training.data import FrameData


def choose_threshold(scores: np.ndarray, target: np.ndarray, classes) -> float:
    """Binary: Youden's J; multiclass: micro-F1 of Emergency under the override rule."""
    e = list(classes).index(Decision.EMERGENCY)
    positive = target == e
    if len(classes) == 2:
        return youden_threshold(scores[:, e], positive)
    return override_threshold(scores, positive, e)


@dataclass(frozen=True)
class StreamScores:
    """Scores of every frame of some sequences (frames in data order)."""

    data: FrameData
    sequences: np.ndarray  # sequence indices
    scores: np.ndarray  # (n_frames_of_those_sequences, k)
    # The delay-filtered decisions (class index) the robot's frame path made (vigil.replay);
    # None: derive them from the scores with the batch form of the same policy.
    decisions: np.ndarray | None = None

    def decisions_of(self, sequence: int) -> np.ndarray | None:
        if self.decisions is None:
            return None
        group = self.data.group[self.data.frames_of(self.sequences)]
        return self.decisions[group == sequence]

    def per_sequence(self):
        mask = self.data.frames_of(self.sequences)
        group = self.data.group[mask]
        times, target = self.data.timestamps[mask], self.data.target[mask]
        for s in self.sequences:
            rows = group == s
            yield int(s), times[rows], target[rows], self.scores[rows]


def _first_emergency(times, target, e):
    hits = np.flatnonzero(target == e)
    return float(times[hits[0]]) if hits.size else None


def events_for(stream: StreamScores, threshold: float, delay_s: float) -> tuple[list, np.ndarray]:
    """Per-sequence events and the delay-filtered decisions of all frames."""
    classes = stream.data.classes
    e, normal = classes.index(Decision.EMERGENCY), classes.index(Decision.NORMAL)
    events, filtered_all = [], []
    for s, times, target, scores in stream.per_sequence():
        filtered = stream.decisions_of(s)
        if filtered is None:
            raw = raw_decisions(scores, classes, threshold)
            filtered = apply_delay(raw, times, delay_s, normal)
        filtered_all.append(filtered)
        events.append(
            SequenceEvent(
                name=stream.data.names[s],
                positive=bool(stream.data.is_positive_sequence[s]),
                first_emergency_s=_first_emergency(times, target, e),
                alarm_times_s=tuple(float(t) for t in times[alarm_mask(filtered, e)]),
            )
        )
    return events, (np.concatenate(filtered_all) if filtered_all else np.zeros(0, int))


def choose_delay(stream: StreamScores, threshold: float) -> tuple[float, dict]:
    """Delay (0-1.5 s, 10 ms steps) maximising event F1 (falls detected vs sequences with a false
    alarm) on training predictions; ties go to the shorter delay (equal event results: the alarm
    gets out sooner), then to the higher frame F1 after the filter."""
    classes = stream.data.classes
    e = classes.index(Decision.EMERGENCY)
    n = len(DELAY_GRID_S)
    detected, missed, false_alarm = np.zeros(n), np.zeros(n), np.zeros(n)
    tp, fp, fn = np.zeros(n), np.zeros(n), np.zeros(n)
    binary = len(classes) == 2
    for s, times, target, scores in stream.per_sequence():
        raw = raw_decisions(scores, classes, threshold)
        positive = bool(stream.data.is_positive_sequence[s])
        first_e = _first_emergency(times, target, e)
        scored = target >= 0
        if binary:
            alarms = alarm_times_over_delays(raw == e, times)
        for k, delay in enumerate(DELAY_GRID_S):
            if binary:
                alarm_times = alarms[k]
            else:
                filtered_k = apply_delay(raw, times, delay, classes.index(Decision.NORMAL))
                alarm_times = list(times[alarm_mask(filtered_k, e)])
            event = SequenceEvent("", positive, first_e, tuple(alarm_times))
            if positive and first_e is not None:
                detected[k] += event.detected
                missed[k] += not event.detected
            false_alarm[k] += event.false_alarm
        # Frame counts after the filter (a full filter run per delay is cheap per sequence).
        for k, delay in enumerate(DELAY_GRID_S):
            filtered = apply_delay(raw, times, delay, classes.index(Decision.NORMAL))
            pred, true = filtered[scored] == e, target[scored] == e
            tp[k] += np.sum(pred & true)
            fp[k] += np.sum(pred & ~true)
            fn[k] += np.sum(~pred & true)
    f1_event = np.array(
        [event_f1(d, m, f) for d, m, f in zip(detected, missed, false_alarm, strict=True)]
    )
    f1_frame = f1_from_counts(tp, fp, fn)
    order = np.lexsort((-f1_frame, DELAY_GRID_S, -f1_event))
    best = int(order[0])
    sweep = {
        "delay_s": DELAY_GRID_S.tolist(),
        "event_f1": f1_event.tolist(),
        "frame_f1_filtered": f1_frame.tolist(),
        "falls_detected": detected.tolist(),
        "false_alarm_sequences": false_alarm.tolist(),
    }
    return float(DELAY_GRID_S[best]), sweep


JOINT_THRESHOLDS = tuple(round(0.1 * k, 1) for k in range(1, 10))


def choose_operating_point(
    stream: StreamScores, scores: np.ndarray, target: np.ndarray, rule: str = "youden"
) -> tuple[float, float, dict]:
    """(threshold, delay_s, delay sweep) on training predictions.

    `youden` (the paper's rule): the threshold by Youden's J (multiclass: micro-F1 of Emergency),
    then the delay by event F1. `event`: threshold and delay together by event F1 (ties to the
    higher frame F1 after the filter), over the Youden threshold and 0.1-0.9; Youden's J favours
    frame recall, which the delay filter then has to buy back with a long delay. Multiclass models
    always use the paper's rule (event F1 counts only Emergency events, not Pause)."""
    classes = stream.data.classes
    youden = choose_threshold(scores, target, classes)
    if rule == "youden" or len(classes) != 2:
        return (youden, *choose_delay(stream, youden))
    if rule != "event":
        raise ValueError(f"unknown operating point rule {rule!r}; known: youden, event")
    best = None
    for threshold in sorted({youden, *JOINT_THRESHOLDS}):
        delay_s, sweep = choose_delay(stream, threshold)
        k = int(np.argmin(np.abs(np.asarray(sweep["delay_s"]) - delay_s)))
        key = (sweep["event_f1"][k], sweep["frame_f1_filtered"][k], -delay_s)
        if best is None or key > best[0]:
            best = (key, float(threshold), delay_s, sweep)
    return best[1], best[2], {**best[3], "threshold": best[1], "youden_threshold": youden}


#: Bins of "seconds since the sequence's first Emergency-labelled frame" for recall_by_onset.
ONSET_BINS_S = (0.0, 0.2, 0.4, 0.6, 1.0, float("inf"))


def onset_bin_label(row: dict) -> str:
    """A recall_by_onset row's time range as text: '0.2-0.4 s' or 'from 1 s on'."""
    if row["to_s"] is None:
        return f"from {row['from_s']:g} s on"
    return f"{row['from_s']:g}-{row['to_s']:g} s"


def _onset_seconds(stream: StreamScores, e: int) -> np.ndarray:
    """Per frame of the stream: seconds since its sequence's first Emergency label (NaN before
    it and in sequences without one)."""
    since = []
    for _, times, target, _ in stream.per_sequence():
        first = _first_emergency(times, target, e)
        since.append(times - first if first is not None else np.full(len(times), np.nan))
    return np.concatenate(since) if since else np.zeros(0)


def _recall_by_onset(emergency_onset_s: np.ndarray, caught: np.ndarray) -> list[dict]:
    """Frame recall (before the delay filter) of Emergency frames binned by time since the first
    Emergency label of their sequence: shows which part of a fall the missed frames are in."""
    rows = []
    for low, high in zip(ONSET_BINS_S[:-1], ONSET_BINS_S[1:], strict=True):
        in_bin = (emergency_onset_s >= low - TIME_EPSILON) & (
            emergency_onset_s < high - TIME_EPSILON
        )
        frames = int(in_bin.sum())
        rows.append(
            {
                "from_s": low,
                "to_s": None if np.isinf(high) else high,
                "emergency_frames": frames,
                "missed": int(np.sum(in_bin & ~caught)),
            }
        )
    return rows


def evaluate(stream: StreamScores, threshold: float, delay_s: float) -> dict:
    return evaluate_folds([(stream, threshold, delay_s)])


def evaluate_folds(folds: list[tuple[StreamScores, float, float]]) -> dict:
    """Table 3 columns plus per-event results over held-out folds, each fold with the threshold
    and delay chosen on its own training sequences."""
    tp = fp = fn = fp_d = fn_d = 0
    events, stable, onset_s, caught = [], [], [], []
    for stream, threshold, delay_s in folds:
        classes = stream.data.classes
        e = classes.index(Decision.EMERGENCY)
        target = stream.data.target[stream.data.frames_of(stream.sequences)]
        scored = target >= 0
        raw = raw_decisions(stream.scores, classes, threshold)
        fold_events, filtered = events_for(stream, threshold, delay_s)
        true = target[scored] == e
        pred, pred_d = raw[scored] == e, filtered[scored] == e
        tp += int(np.sum(pred & true))
        fp += int(np.sum(pred & ~true))
        fn += int(np.sum(~pred & true))
        fp_d += int(np.sum(pred_d & ~true))
        fn_d += int(np.sum(~pred_d & true))
        events += fold_events
        stable += _time_to_stable(stream, filtered, e)
        onset_s.append(_onset_seconds(stream, e)[scored][true])
        caught.append(pred[true])
    return {
        "frame_recall": tp / max(tp + fn, 1),
        "frame_precision": tp / max(tp + fp, 1),
        "frame_f1": float(f1_from_counts(tp, fp, fn)),
        "fp": fp,
        "fp_d": fp_d,
        "fp_d_over_fp": fp_d / fp if fp else None,
        "fn": fn,
        "fn_d": fn_d,
        "fn_d_over_fn": fn_d / fn if fn else None,
        **summarise(events),
        "time_to_stable_s": {
            "max": max(stable) if stable else None,
            "mean": float(np.mean(stable)) if stable else None,
            "std": float(np.std(stable)) if stable else None,
        },
        "recall_by_onset": _recall_by_onset(
            np.concatenate(onset_s) if onset_s else np.zeros(0),
            np.concatenate(caught) if caught else np.zeros(0, bool),
        ),
        "fold_operating_points": [
            {"threshold": t, "delay_ms": int(round(d * 1000))} for _, t, d in folds
        ],
        "events": [
            {
                "sequence": ev.name,
                "kind": "fall" if ev.positive else "adl",
                "alarms": len(ev.alarm_times_s),
                "detected": ev.detected if ev.positive else None,
                "false_alarm": ev.false_alarm,
                "time_to_alarm_s": ev.time_to_alarm_s,
            }
            for ev in events
        ],
    }


CURVE_KEYS = (
    "falls_detected",
    "falls_total",
    "adl_false_alarms",
    "adl_total",
    "median_time_to_alarm_s",
    "frame_recall",
    "frame_f1",
)


def operating_curve(
    streams: list[StreamScores], thresholds, delays_s
) -> list[dict[str, float | int | None]]:
    """Fixed operating points over held-out scores, nothing chosen: for every (threshold, delay),
    falls detected, daily-activity sequences with a false alarm, median time to alarm and frame
    recall and F1. Shows what the model could do if the operating point were known, apart from
    how well training predictions choose it."""
    rows = []
    for threshold in thresholds:
        for delay_s in delays_s:
            fixed = [(stream, float(threshold), float(delay_s)) for stream in streams]
            result = evaluate_folds(fixed)
            rows.append(
                {
                    "threshold": float(threshold),
                    "delay_ms": int(round(float(delay_s) * 1000)),
                    **{key: result[key] for key in CURVE_KEYS},
                }
            )
    return rows


def _time_to_stable(stream: StreamScores, filtered: np.ndarray, e: int) -> list[float]:
    """Per fall: time from the first Emergency label until the filtered decision stops changing."""
    times_all = stream.data.timestamps[stream.data.frames_of(stream.sequences)]
    group = stream.data.group[stream.data.frames_of(stream.sequences)]
    target = stream.data.target[stream.data.frames_of(stream.sequences)]
    values = []
    for s in stream.sequences:
        if not stream.data.is_positive_sequence[s]:
            continue
        rows = group == s
        times, dec, tgt = times_all[rows], filtered[rows], target[rows]
        first = np.flatnonzero(tgt == e)
        if not first.size:
            continue
        after = dec[first[0] :]
        changes = np.flatnonzero(after[1:] != after[:-1])
        last_change = times[first[0] + changes[-1] + 1] if changes.size else times[first[0]]
        values.append(float(last_change - times[first[0]]))
    return values
