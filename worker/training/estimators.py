"""The model families as scikit-learn pipelines, their grids, and the paper's SVM configuration.

A family is a pipeline factory (FAMILIES); a ModelSpec names a family, a feature set and a grid
of that family's hyperparameters. Every family is selected by worker.training.detector's
EmergencyDetector (grid search, inner cross-validation, threshold and delay), the window model
`tcn` too: its pipeline's model scores a frame on the frames before it in its stream
(`takes_streams`), so it is fitted and scored on whole streams with their `groups`. The specs
themselves, by unique name, are registered in worker.training.specs. Grid keys are the model
step's parameter names, except `gamma_times_1_over_n` (SVM): the paper's gamma is 1/n_features,
and since n_features is fixed by the feature set, the grid carries SVC's gamma as
`gamma_times_1_over_n / n_features`, the very value (same float division) the SVC was built with
before.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier, RandomForestClassifier
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC


def _svm(seed: int) -> Pipeline:
    return Pipeline([("scale", StandardScaler()), ("model", SVC(kernel="poly", cache_size=500))])


def _mlp(seed: int) -> Pipeline:
    model = MLPClassifier(max_iter=80, early_stopping=True, n_iter_no_change=8, random_state=seed)
    return Pipeline([("scale", StandardScaler()), ("model", model)])


# Trees need no scaling. Without it the ONNX graph compares the very same float32 inputs with the
# split values; with it, ONNX's float32 scaler rounds differently from scikit-learn's and a value
# next to a split can land on the other side.
def _rf(seed: int) -> Pipeline:
    model = RandomForestClassifier(class_weight="balanced_subsample", n_jobs=2, random_state=seed)
    return Pipeline([("model", model)])


def _gbt(seed: int) -> Pipeline:
    return Pipeline(
        [("model", HistGradientBoostingClassifier(early_stopping=False, random_state=seed))]
    )


def _tcn(seed: int) -> Pipeline:
    # torch is imported only where a window model is built
    from worker.training.temporal import TemporalClassifier

    return Pipeline([("model", TemporalClassifier(seed=seed))])


#: family -> pipeline factory (seed -> unfitted pipeline holding the family's constants).
FAMILIES: dict[str, Callable[[int], Pipeline]] = {
    "svm": _svm,
    "mlp": _mlp,
    "rf": _rf,
    "gbt": _gbt,
    "tcn": _tcn,
}


def takes_streams(pipeline: Pipeline) -> bool:
    """Whether the pipeline's model scores a frame on the frames before it in its stream (the
    window model): it is fitted on whole streams, frames not to train on marked with a negative
    class index, and its fit and predict_proba take each frame's stream (`groups`)."""
    return bool(getattr(pipeline.steps[-1][1], "takes_streams", False))


def fit_pipeline(pipeline: Pipeline, X, y, groups=None) -> Pipeline:
    """`pipeline.fit(X, y)`, with the frames' streams for a model that takes them."""
    if takes_streams(pipeline):
        return pipeline.fit(X, y, **{f"{pipeline.steps[-1][0]}__groups": groups})
    return pipeline.fit(X, y)


def pipeline_params(params: dict[str, Any], n_features: int) -> dict[str, Any]:
    """A configuration (grid keys) as the pipeline's parameters."""
    out = {}
    for key, value in params.items():
        if key == "gamma_times_1_over_n":
            out["model__gamma"] = value / n_features
        else:
            out[f"model__{key}"] = value
    return out


@dataclass(frozen=True)
class ModelSpec:
    name: str
    family: str  # a key of FAMILIES
    grid: dict[str, list[Any]]
    feature_set: str = "full"
    description: str = ""
    fixed: dict[str, Any] = field(default_factory=dict)
    # How threshold and delay are chosen (worker.training.selection.choose_operating_point).
    operating_point: str = "event"

    def configurations(self) -> list[dict[str, Any]]:
        """Every point of the grid, the last key varying fastest (the order grids are reported
        and ties are broken in)."""
        keys = list(self.grid)
        return [
            dict(zip(keys, values, strict=True))
            for values in itertools.product(*self.grid.values())
        ]

    def pipeline(self, n_features: int, seed: int = 0) -> Pipeline:
        """The family's unfitted pipeline with the spec's fixed parameters set."""
        if self.family not in FAMILIES:
            raise ValueError(f"unknown family {self.family!r}; known: {', '.join(FAMILIES)}")
        return FAMILIES[self.family](seed).set_params(**pipeline_params(self.fixed, n_features))

    def param_grid(self, n_features: int) -> list[dict[str, list[Any]]]:
        """The grid as GridSearchCV's param_grid: one single-point grid per configuration, so
        candidates keep the order of `configurations()`."""
        return [
            {key: [value] for key, value in pipeline_params(params, n_features).items()}
            for params in self.configurations()
        ]


def positive_scores(pipeline: Pipeline, features: np.ndarray, groups=None) -> np.ndarray:
    """(n, k) class scores as the exported ONNX graph computes them (`groups`: each frame's
    stream, for a model that takes streams; None: one stream)."""
    if takes_streams(pipeline):
        return pipeline.predict_proba(features, groups=groups)
    if isinstance(pipeline.steps[-1][1], SVC):
        p = 1.0 / (1.0 + np.exp(-pipeline.decision_function(features)))
        return np.stack([1 - p, p], axis=1)
    return pipeline.predict_proba(features)
