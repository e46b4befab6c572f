"""Score / export for one model spec, on whole sequences of a FrameData."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from vigil.features import FEATURE_SETS
from worker.training.data import FrameData
from worker.training.detector import EmergencyDetector
from worker.training.estimators import ModelSpec, positive_scores, takes_streams
from worker.training.export import sklearn_to_onnx


class Trainer(Protocol):
    name: str
    feature_set: str

    def configurations(self) -> list[dict[str, Any]]: ...
    def window_of(self, fitted: Any) -> int: ...
    def score(self, fitted: Any, data: FrameData, sequences: np.ndarray) -> np.ndarray: ...
    def to_onnx(self, fitted: Any, data: FrameData) -> bytes: ...
    def reference(self, fitted: Any, data: FrameData, n: int) -> tuple[np.ndarray, np.ndarray]: ...


class SklearnTrainer:
    """A ModelSpec's models: selected and fitted by EmergencyDetector, scored and exported here
    (`fitted` is the detector's `model_`, a pipeline over the spec's feature columns). Every
    family, the window model (`tcn`) too: its pipeline scores each frame on the last `window`
    frames of its sequence and is exported from torch (worker.training.temporal.to_onnx), with
    input (batch, window, n_features)."""

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

    def window_of(self, fitted) -> int:
        """How many frames the model reads per decision (the manifest's `window`)."""
        return int(fitted.steps[-1][1].window) if takes_streams(fitted) else 1

    def score(self, fitted, data: FrameData, sequences: np.ndarray) -> np.ndarray:
        mask = data.frames_of(sequences)
        return positive_scores(fitted, data.features[mask][:, self.columns], data.group[mask])

    def to_onnx(self, fitted, data: FrameData) -> bytes:
        if takes_streams(fitted):
            from worker.training.temporal import to_onnx

            return to_onnx(fitted.steps[-1][1])
        return sklearn_to_onnx(fitted, data.features[data.trainable][:, self.columns])

    def reference(self, fitted, data: FrameData, n: int = 256):
        """(inputs, scores) of up to `n` trainable frames, inputs as the ONNX graph takes them
        (a window model's: each frame's window)."""
        rows = np.flatnonzero(data.trainable)
        rows = rows[np.linspace(0, len(rows) - 1, min(n, len(rows))).astype(int)]
        if takes_streams(fitted):
            X, groups = data.features[:, self.columns], data.group
            classifier = fitted.steps[-1][1]
            return classifier.windows(X, groups)[rows], positive_scores(fitted, X, groups)[rows]
        features = data.features[rows][:, self.columns]
        return features, positive_scores(fitted, features)
