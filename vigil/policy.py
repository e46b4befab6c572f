"""The decision policy, identical in evaluation and on the robot.

Threshold rule: Emergency whenever its score reaches the threshold, else the arg-max class (for a
binary model this is simply p_emergency >= t). Delay filter: a change to Emergency or Pause is
raised only once the raw decision has held for `delay_s` seconds (by frame timestamps); a change
back to Normal is immediate; while a change is pending the previous decision stays.

Lost while falling (``LostWhileFalling``, issue #34): a rule beside the model, applied in the
frame path (vigil.detector) on the robot, in replay and in the benchmark: a patient whose hips
were going down fast when the pose estimator lost them is an Emergency from that frame on.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np

from vigil.classes import Decision
from vigil.skeleton import INDEX, SkeletonFrame
from vigil.tracking import body_keypoints

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


# --- a patient lost while falling (issue #34) ------------------------------------------------

#: Downward speed of the hip centre, in torso lengths per second, at or above which a patient the
#: pose estimator then loses is taken to have fallen. Set on URFD's MoveNet keypoints: the fastest
#: such descent before a loss in the 40 daily activities is 1.65 (adl-20), in the falls up to 4.8.
LOST_FALL_SPEED = 2.0
#: The descent is the slope of the hip centre's height over the patient's whole-body frames in
#: this window before they were lost (at least LOST_FALL_MIN_FRAMES of them), and the loss must
#: come within it.
LOST_FALL_WINDOW_S = 0.3
LOST_FALL_MIN_FRAMES = 3
#: The torso length is the longest seen in this last stretch (it shortens as a body tips over).
LOST_FALL_TORSO_MEMORY_S = 1.0
#: A whole-body frame has at least this many of the 13 body joints (vigil.tracking.BODY_JOINTS),
#: the neck and the hip centre: partial detections move the hip centre by their own errors.
LOST_FALL_BODY_KEYPOINTS = 10
#: Fewer keypoints than this and the patient counts as lost (the feature extractor's usable pose).
LOST_FALL_USABLE_KEYPOINTS = 4
LOST_WHILE_FALLING = "lost_while_falling"


class LostWhileFalling:
    """A patient lost while falling is an Emergency, at once: when the tracked patient's hips
    were going down at LOST_FALL_SPEED torso lengths per second or faster over their last
    LOST_FALL_WINDOW_S and the pose estimator then loses them (no patient passed on, or too few
    keypoints for a pose), ``update`` returns True from the frame they are lost until they are
    seen again; the model decides again from then on. Scale-free (torso lengths), by timestamps
    (any frame rate). One stream; reset() between streams."""

    def __init__(
        self,
        speed: float = LOST_FALL_SPEED,
        window_s: float = LOST_FALL_WINDOW_S,
        min_frames: int = LOST_FALL_MIN_FRAMES,
        torso_memory_s: float = LOST_FALL_TORSO_MEMORY_S,
        body_keypoints: int = LOST_FALL_BODY_KEYPOINTS,
    ) -> None:
        self.speed = speed
        self.window_s = window_s
        self.min_frames = min_frames
        self.torso_memory_s = torso_memory_s
        self.body_keypoints = body_keypoints
        self.reset()

    def reset(self) -> None:
        self._history: deque[tuple[float, float, float]] = deque()  # (t, hip y, torso length)
        self._lost = False
        self.active_ = False
        self.descent_ = float("nan")  # torso lengths per second at the last loss

    def descent(self) -> float:
        """Downward speed of the hip centre over the window before the last whole-body frame,
        in torso lengths per second (NaN without enough frames)."""
        if not self._history:
            return float("nan")
        last = self._history[-1][0]
        window = [h for h in self._history if h[0] >= last - self.window_s - TIME_EPSILON]
        if len(window) < self.min_frames:
            return float("nan")
        t, y, _ = (np.asarray(v, np.float64) for v in zip(*window, strict=True))
        torso = max(h[2] for h in self._history)
        if torso <= 0 or np.ptp(t) <= 0:
            return float("nan")
        return float(np.polyfit(t - t[0], y, 1)[0] / torso)

    def update(self, frame: SkeletonFrame, seen: bool) -> bool:
        """True while the patient is lost after a fast descent (Emergency)."""
        kp = frame.keypoints
        t = float(frame.timestamp)
        if seen and int((kp[:, 2] > 0).sum()) >= LOST_FALL_USABLE_KEYPOINTS:
            self._lost = self.active_ = False
            neck, hip = kp[INDEX["neck"]], kp[INDEX["mid_hip"]]
            if body_keypoints(kp) >= self.body_keypoints and neck[2] > 0 and hip[2] > 0:
                torso = float(np.linalg.norm(neck[:2] - hip[:2]))
                self._history.append((t, float(hip[1]), torso))
            while self._history and self._history[0][0] < t - self.torso_memory_s - TIME_EPSILON:
                self._history.popleft()
            return False
        if not self._lost:  # the frame the patient is lost: judge the descent before it
            self._lost = True
            recent = (
                bool(self._history) and t - self._history[-1][0] <= self.window_s + TIME_EPSILON
            )
            self.descent_ = self.descent() if recent else float("nan")
            self.active_ = bool(self.descent_ >= self.speed)  # NaN compares False
        return self.active_
