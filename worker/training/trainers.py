"""Score / export for one model family, on whole sequences of a FrameData."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from vigil.features import FEATURE_SETS
from worker.training.data import FrameData
from worker.training.detector import EmergencyDetector
from worker.training.estimators import ModelSpec, positive_scores
from worker.training.export import sklearn_to_onnx


class Trainer(Protocol):
    name: str
    feature_set: str
    window: int

    def configurations(self) -> list[dict[str, Any]]: ...
    def score(self, fitted: Any, data: FrameData, sequences: np.ndarray) -> np.ndarray: ...
    def to_onnx(self, fitted: Any, data: FrameData) -> bytes: ...
    def reference(self, fitted: Any, data: FrameData, n: int) -> tuple[np.ndarray, np.ndarray]: ...


class SklearnTrainer:
    """A ModelSpec's models: selected and fitted by EmergencyDetector, scored and exported here
    (`fitted` is the detector's `model_`, a pipeline over the spec's feature columns)."""

    window = 1

    def __init__(self, spec: ModelSpec, seed: int = 0) -> None:
        self.spec, self.seed = spec, seed
        self.name, self.feature_set = spec.name, spec.feature_set
        self.operating_point = spec.operating_point

    @property
    def columns(self) -> np.ndarray:
        return FEATURE_SETS[self.feature_set]

    def configurations(self) -> list[dict[str, Any]]:
        return self.spec.configurations()

    def detector(
        self, mode: str, n_inner: int, stride: int, n_jobs: int | None = None
    ) -> EmergencyDetector:
        return EmergencyDetector.from_spec(
            self.spec, mode=mode, n_inner=n_inner, stride=stride, seed=self.seed, n_jobs=n_jobs
        )

    def score(self, fitted, data: FrameData, sequences: np.ndarray) -> np.ndarray:
        features = data.features[data.frames_of(sequences)][:, self.columns]
        return positive_scores(fitted, features)

    def to_onnx(self, fitted, data: FrameData) -> bytes:
        return sklearn_to_onnx(fitted, data.features[data.trainable][:, self.columns])

    def reference(self, fitted, data: FrameData, n: int = 256):
        rows = np.flatnonzero(data.trainable)
        rows = rows[np.linspace(0, len(rows) - 1, min(n, len(rows))).astype(int)]
        features = data.features[rows][:, self.columns]
        return features, positive_scores(fitted, features)
