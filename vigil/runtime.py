"""Per-frame classification on the robot (and in replay): features -> ONNX model -> policy."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vigil.classes import Decision
from vigil.features import FEATURE_VERSION, FeatureExtractor
from vigil.model_file import Classifier, load_classifier
from vigil.policy import DecisionPolicy
from vigil.skeleton import SkeletonFrame


@dataclass(frozen=True, slots=True)
class Classification:
    decision: Decision  # after threshold rule and delay filter
    scores: dict[Decision, float]
    model_version: str
    threshold: float
    delay_ms: int
    pending: bool  # a change to Emergency/Pause is waiting for the delay
    raw_decision: Decision | None = None  # before the delay filter
    rule: str | None = None  # a rule beside the model decided (vigil.policy.LOST_WHILE_FALLING)


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

    def scores(self, frame: SkeletonFrame) -> np.ndarray:
        features = self.extractor.push(frame)
        if self.manifest.window == 1:
            return self.classifier.predict_proba(features[None])[0]
        if not self._window:  # pad the start of a stream with its first frame
            self._window.extend([features] * (self.manifest.window - 1))
        self._window.append(features)
        return self.classifier.predict_proba(np.stack(self._window)[None])[0]

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
