"""Event-level evaluation of delay-filtered decisions, and the vectorised delay sweep (binary).

Definitions (binding, so figures compare across versions): an alarm is the delay-filtered decision
turning Emergency; a positive (fall) sequence counts as detected when an alarm is raised no earlier
than EARLY_TOLERANCE_S before its first Emergency-labelled frame (an earlier alarm is a false
alarm); a negative (daily-activity) sequence has a false alarm when any alarm is raised in it;
time to alarm runs from the first Emergency-labelled frame to the alarm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vigil.policy import TIME_EPSILON

EARLY_TOLERANCE_S = 0.5
DELAY_GRID_S = np.round(np.arange(0, 151) * 0.01, 2)  # 0 .. 1.5 s in 10 ms steps


@dataclass(frozen=True, slots=True)
class SequenceEvent:
    name: str
    positive: bool
    first_emergency_s: float | None
    alarm_times_s: tuple[float, ...]

    @property
    def detected(self) -> bool:
        return self.detection_time_s is not None

    @property
    def detection_time_s(self) -> float | None:
        if not self.positive or self.first_emergency_s is None:
            return None
        earliest = self.first_emergency_s - EARLY_TOLERANCE_S - TIME_EPSILON
        valid = [t for t in self.alarm_times_s if t >= earliest]
        return valid[0] if valid else None

    @property
    def time_to_alarm_s(self) -> float | None:
        t = self.detection_time_s
        return None if t is None else t - self.first_emergency_s

    @property
    def false_alarm(self) -> bool:
        if not self.positive or self.first_emergency_s is None:
            return bool(self.alarm_times_s)
        earliest = self.first_emergency_s - EARLY_TOLERANCE_S - TIME_EPSILON
        return any(t < earliest for t in self.alarm_times_s)


def summarise(events: list[SequenceEvent]) -> dict[str, float | int | None]:
    falls = [e for e in events if e.positive]
    adls = [e for e in events if not e.positive]
    times = [e.time_to_alarm_s for e in falls if e.detected]
    detected = sum(e.detected for e in falls)
    false_adl = sum(e.false_alarm for e in adls)
    return {
        "falls_detected": detected,
        "falls_total": len(falls),
        "falls_with_early_alarm": sum(e.false_alarm for e in falls),
        "adl_false_alarms": false_adl,
        "adl_total": len(adls),
        "median_time_to_alarm_s": float(np.median(times)) if times else None,
        "max_time_to_alarm_s": float(np.max(times)) if times else None,
        "event_f1": event_f1(detected, len(falls) - detected, false_adl),
    }


def event_f1(detected: int, missed: int, false_alarm_sequences: int) -> float:
    denom = 2 * detected + missed + false_alarm_sequences
    return 2 * detected / denom if denom else 0.0


def emergency_runs(raw_is_emergency: np.ndarray, timestamps: np.ndarray) -> list[np.ndarray]:
    """Offsets (s) of the frames of each run of raw Emergency from the run's first frame."""
    hit = np.asarray(raw_is_emergency, bool)
    if not hit.any():
        return []
    edges = np.diff(np.concatenate([[0], hit.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [timestamps[a:b] - timestamps[a] for a, b in zip(starts, ends, strict=True)]


def alarm_times_over_delays(
    raw_is_emergency: np.ndarray, timestamps: np.ndarray, delays: np.ndarray = DELAY_GRID_S
) -> list[list[float]]:
    """Binary policy: alarm times of one stream for every delay, without re-running the filter.

    With two classes the filtered decision is Emergency exactly where the raw Emergency run has
    lasted at least d, so each run raises one alarm at its first frame past d (if it gets there).
    """
    timestamps = np.asarray(timestamps, np.float64)
    per_delay: list[list[float]] = [[] for _ in delays]
    hit = np.asarray(raw_is_emergency, bool)
    edges = np.diff(np.concatenate([[0], hit.astype(np.int8), [0]]))
    for start in np.flatnonzero(edges == 1):
        end = start + int(np.argmax(edges[start + 1 :] == -1)) + 1
        offsets = timestamps[start:end] - timestamps[start]
        first = np.searchsorted(offsets, np.asarray(delays) - TIME_EPSILON, side="left")
        for k in np.flatnonzero(first < len(offsets)):
            per_delay[k].append(float(timestamps[start + first[k]]))
    return per_delay
