"""Per-frame classification on the robot (and in replay): features -> ONNX model -> policy.

Frames without a usable pose (the patient not found, or fewer than MIN_KEYPOINTS keypoints: the
features' `held` flag) hold the scores of the last frame with one, for up to HOLD_S seconds of
stream time. A model never sees such frames in training (they are left out), so its scores there
mean nothing; held scores keep the raw decision, so a pose estimator losing the patient for a few
frames mid-fall neither resets the delay filter nor starts it. After HOLD_S (as long as the tracker
keeps looking for a lost patient, 30 frames at 30 frames/s) the model scores the held pose itself.
The batch twin, `hold_scores`, is applied to bulk-scored features in training and evaluation,
so both give the same scores on every frame.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vigil.classes import Decision
from vigil.features import FEATURE_NAMES, FEATURE_SETS, FEATURE_VERSION, FeatureExtractor
from vigil.model_file import Classifier, load_classifier
from vigil.policy import TIME_EPSILON, DecisionPolicy
from vigil.skeleton import SkeletonFrame

#: Seconds of stream time the scores of the last frame with a usable pose hold on frames without
#: one (module docstring). In seconds, not frames: any frame rate and pose estimator.
HOLD_S = 1.0
HELD = FEATURE_NAMES.index("held")


def hold_scores(
    scores: np.ndarray, held: np.ndarray, timestamps: np.ndarray, hold_s: float = HOLD_S
) -> np.ndarray:
    """Scores of one stream with frames flagged ``held`` (no usable pose) replaced by the scores
    of the last frame without the flag, if that was at most ``hold_s`` seconds earlier: the
    batch form of FrameClassifier's hold, identical frame by frame."""
    held = np.asarray(held, bool)
    out = np.array(scores, copy=True)
    n = len(held)
    if not held.any():
        return out
    source = np.maximum.accumulate(np.where(~held, np.arange(n), -1))
    times = np.asarray(timestamps, np.float64)
    ok = held & (source >= 0)
    ok[ok] &= times[ok] - times[source[ok]] <= hold_s + TIME_EPSILON
    out[ok] = scores[source[ok]]
    return out


@dataclass(frozen=True, slots=True)
class Classification:
    decision: Decision  # after threshold rule and delay filter
    scores: dict[Decision, float]
    model_version: str
    threshold: float
    delay_ms: int
    pending: bool  # a change to Emergency/Pause is waiting for the delay
    raw_decision: Decision | None = None  # before the delay filter


class FrameClassifier:
    """One stream (one patient): call reset() when a new transport starts."""

    def __init__(self, classifier: Classifier) -> None:
        manifest = classifier.manifest
        if manifest.feature_version != FEATURE_VERSION:
            raise ValueError(
                f"model needs feature version {manifest.feature_version}, "
                f"this vigil computes {FEATURE_VERSION}"
            )
        self.classifier = classifier
        self.manifest = manifest
        self.extractor = FeatureExtractor(manifest.feature_set)
        self.policy = DecisionPolicy(manifest.classes, manifest.threshold, manifest.delay_ms / 1000)
        self._window: deque[np.ndarray] = deque(maxlen=manifest.window)
        self._held_column = int(np.flatnonzero(FEATURE_SETS[manifest.feature_set] == HELD)[0])
        self._last: tuple[np.ndarray, float] | None = None  # scores, time of the last usable pose
        self.hold_s = HOLD_S

    @property
    def version(self) -> str:
        return self.manifest.version

    @property
    def sha256(self) -> str:
        """sha256 of the model bytes this classifier runs (not what a manifest claims)."""
        return self.classifier.sha256

    @classmethod
    def from_dir(cls, model_dir: Path | str) -> FrameClassifier:
        return cls(load_classifier(model_dir))

    def reset(self) -> None:
        self.extractor.reset()
        self.policy.reset()
        self._window.clear()
        self._last = None

    def scores(self, frame: SkeletonFrame) -> np.ndarray:
        """The model's scores for the frame, or the held ones (module docstring)."""
        features = self.extractor.push(frame)
        if self.manifest.window == 1:
            scores = self.classifier.predict_proba(features[None])[0]
        else:
            if not self._window:  # pad the start of a stream with its first frame
                self._window.extend([features] * (self.manifest.window - 1))
            self._window.append(features)
            scores = self.classifier.predict_proba(np.stack(self._window)[None])[0]
        t = float(frame.timestamp)
        if features[self._held_column] <= 0:
            self._last = (scores.copy(), t)
        elif self._last is not None and t - self._last[1] <= self.hold_s + TIME_EPSILON:
            return self._last[0].copy()
        return scores

    def classify(self, frame: SkeletonFrame) -> Classification:
        scores = self.scores(frame)
        decision = self.policy.update(scores, frame.timestamp)
        return Classification(
            decision=decision,
            scores={c: float(s) for c, s in zip(self.manifest.classes, scores, strict=True)},
            model_version=self.manifest.version,
            threshold=self.manifest.threshold,
            delay_ms=self.manifest.delay_ms,
            pending=self.policy.pending,
            raw_decision=self.policy.raw_decision,
        )
