"""The decision policy, identical in evaluation and on the robot.

Threshold rule: Emergency whenever its score reaches the threshold, else the arg-max class (for a
binary model this is simply p_emergency >= t). Delay filter: a change to Emergency or Pause is
raised only once the raw decision has held for `delay_s` seconds (by frame timestamps); a change
back to Normal is immediate; while a change is pending the previous decision stays.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vigil.classes import Decision

# Timestamps are floats (k/30 s): compare held durations with a tolerance far below a frame.
TIME_EPSILON = 1e-9


def _index(classes: Sequence[Decision], decision: Decision) -> int:
    try:
        return list(classes).index(decision)
    except ValueError:
        raise ValueError(f"classes {list(classes)} lack {decision.value!r}") from None


def raw_decisions(scores: np.ndarray, classes: Sequence[Decision], threshold: float) -> np.ndarray:
    """(n, k) class scores -> (n,) class indices by the emergency-override rule."""
    scores = np.atleast_2d(np.asarray(scores))
    emergency = _index(classes, Decision.EMERGENCY)
    return np.where(scores[:, emergency] >= threshold, emergency, scores.argmax(axis=1))


def run_starts(raw: np.ndarray, timestamps: np.ndarray) -> np.ndarray:
    """Timestamp at which each frame's run of identical raw decisions began."""
    n = len(raw)
    change = np.ones(n, bool)
    change[1:] = raw[1:] != raw[:-1]
    start_index = np.maximum.accumulate(np.where(change, np.arange(n), 0)) if n else change
    return np.asarray(timestamps, np.float64)[start_index]


def apply_delay(
    raw: np.ndarray, timestamps: np.ndarray, delay_s: float, normal_index: int = 0
) -> np.ndarray:
    """Vectorised delay filter over one stream of raw class indices; the stream starts Normal."""
    raw = np.asarray(raw)
    timestamps = np.asarray(timestamps, np.float64)
    n = len(raw)
    if n == 0:
        return raw.copy()
    settled = (raw == normal_index) | (
        timestamps - run_starts(raw, timestamps) >= delay_s - TIME_EPSILON
    )
    source = np.maximum.accumulate(np.where(settled, np.arange(n), -1))
    return np.where(source >= 0, raw[np.maximum(source, 0)], normal_index)


def alarm_mask(decisions: np.ndarray, target_index: int) -> np.ndarray:
    """Frames where the (filtered) decision turns into `target_index`."""
    hit = np.asarray(decisions) == target_index
    turned = hit.copy()
    turned[1:] &= ~hit[:-1]
    return turned


class DecisionPolicy:
    """Streaming threshold rule + delay filter for one stream; reset() between streams."""

    def __init__(self, classes: Sequence[Decision], threshold: float, delay_s: float) -> None:
        self.classes = tuple(Decision(c) for c in classes)
        if Decision.NORMAL not in self.classes or Decision.EMERGENCY not in self.classes:
            raise ValueError("classes must include normal and emergency")
        if not 0.0 <= threshold <= 1.0:
            raise ValueError(f"threshold must be within 0..1, got {threshold}")
        if delay_s < 0:
            raise ValueError(f"delay_s must not be negative, got {delay_s}")
        self.threshold = float(threshold)
        self.delay_s = float(delay_s)
        self._normal = self.classes.index(Decision.NORMAL)
        self.reset()

    def reset(self) -> None:
        self._raw: int | None = None
        self._run_start = 0.0
        self._output = self._normal

    @property
    def decision(self) -> Decision:
        return self.classes[self._output]

    @property
    def raw_decision(self) -> Decision | None:
        return None if self._raw is None else self.classes[self._raw]

    @property
    def pending(self) -> bool:
        """A change to Emergency or Pause is waiting for its delay to pass."""
        return self._raw is not None and self._raw != self._output

    @property
    def pending_decision(self) -> Decision | None:
        return self.classes[self._raw] if self.pending else None

    def update(self, scores: np.ndarray, timestamp: float) -> Decision:
        scores = np.asarray(scores, np.float64).reshape(1, -1)
        if scores.shape[1] != len(self.classes):
            raise ValueError(f"expected {len(self.classes)} scores, got {scores.shape[1]}")
        raw = int(raw_decisions(scores, self.classes, self.threshold)[0])
        if raw != self._raw:
            self._raw, self._run_start = raw, float(timestamp)
        if raw == self._normal or timestamp - self._run_start >= self.delay_s - TIME_EPSILON:
            self._output = raw
        return self.decision
