"""The model families with their four-hyperparameter grids, and the paper's SVM configuration."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier, RandomForestClassifier
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC


@dataclass(frozen=True)
class ModelSpec:
    name: str
    family: str  # svm, mlp, rf
    grid: dict[str, list[Any]]
    feature_set: str = "full"
    description: str = ""
    fixed: dict[str, Any] = field(default_factory=dict)
    # How threshold and delay are chosen (worker.training.selection.choose_operating_point).
    operating_point: str = "event"

    def configurations(self) -> list[dict[str, Any]]:
        keys = list(self.grid)
        return [
            dict(zip(keys, values, strict=True))
            for values in itertools.product(*self.grid.values())
        ]

    def build(self, params: dict[str, Any], n_features: int, seed: int = 0) -> Pipeline:
        params = {**self.fixed, **params}
        if self.family == "svm":
            gamma = params["gamma_times_1_over_n"] / n_features
            model = SVC(
                kernel="poly",
                degree=params["degree"],
                C=params["C"],
                gamma=gamma,
                coef0=params.get("coef0", 0.0),
                class_weight=params.get("class_weight"),
                cache_size=500,
            )
        elif self.family == "mlp":
            model = MLPClassifier(
                hidden_layer_sizes=params["hidden_layer_sizes"],
                alpha=params["alpha"],
                learning_rate_init=params["learning_rate_init"],
                activation=params["activation"],
                max_iter=80,
                early_stopping=True,
                n_iter_no_change=8,
                random_state=seed,
            )
        elif self.family == "rf":
            model = RandomForestClassifier(
                n_estimators=params["n_estimators"],
                max_depth=params["max_depth"],
                min_samples_leaf=params["min_samples_leaf"],
                max_features=params["max_features"],
                class_weight="balanced_subsample",
                n_jobs=2,
                random_state=seed,
            )
        elif self.family == "gbt":
            model = HistGradientBoostingClassifier(
                max_iter=params["max_iter"],
                learning_rate=params["learning_rate"],
                max_leaf_nodes=params["max_leaf_nodes"],
                l2_regularization=params["l2_regularization"],
                early_stopping=False,
                random_state=seed,
            )
        else:
            raise ValueError(f"unknown family {self.family!r}")
        if self.family in ("rf", "gbt"):
            # Trees need no scaling. Without it the ONNX graph compares the very same float32
            # inputs with the split values; with it, ONNX's float32 scaler rounds differently
            # from scikit-learn's and a value next to a split can land on the other side.
            return Pipeline([("model", model)])
        return Pipeline([("scale", StandardScaler()), ("model", model)])


def positive_scores(pipeline: Pipeline, features: np.ndarray) -> np.ndarray:
    """(n, k) class scores as the exported ONNX graph computes them."""
    if isinstance(pipeline.steps[-1][1], SVC):
        p = 1.0 / (1.0 + np.exp(-pipeline.decision_function(features)))
        return np.stack([1 - p, p], axis=1)
    return pipeline.predict_proba(features)


PAPER_SVM = ModelSpec(
    name="svm-paper",
    family="svm",
    grid={"degree": [2], "C": [0.5], "gamma_times_1_over_n": [1.0], "class_weight": [None]},
    feature_set="pose",
    operating_point="youden",
    description="Zachariae et al.: SVM, poly kernel degree 2, C=0.5, gamma=1/n_features, "
    "single-frame pose features",
)
SVM = ModelSpec(
    name="svm",
    family="svm",
    grid={
        "degree": [2, 3],
        "C": [0.5, 4.0],
        "gamma_times_1_over_n": [1.0, 4.0],
        "class_weight": [None, "balanced"],
    },
    fixed={"coef0": 1.0},
    description="SVM, poly kernel, pose + temporal features",
)
MLP = ModelSpec(
    name="mlp",
    family="mlp",
    grid={
        "hidden_layer_sizes": [(64,), (128, 64)],
        "alpha": [1e-4, 1e-2],
        "learning_rate_init": [1e-3, 3e-3],
        "activation": ["relu", "tanh"],
    },
    description="MLP, pose + temporal features",
)
RF = ModelSpec(
    name="rf",
    family="rf",
    grid={
        "n_estimators": [60, 150],
        "max_depth": [8, 16],
        "min_samples_leaf": [1, 5],
        "max_features": ["sqrt", 0.3],
    },
    description="Random forest, pose + temporal features",
)
GBT = ModelSpec(
    name="gbt",
    family="gbt",
    grid={
        "max_iter": [100, 200],
        "learning_rate": [0.1],
        "max_leaf_nodes": [15, 31],
        "l2_regularization": [0.0, 1.0],
    },
    description="Gradient-boosted trees (histogram), pose, temporal and floor features",
)
GBT_KEYPOINTS = ModelSpec(
    name="gbt-keypoints",
    family="gbt",
    grid=GBT.grid,
    feature_set="keypoints",
    description="Gradient-boosted trees without floor measures, for robots whose depth camera "
    "has no calibrated mount",
)
SPECS: dict[str, ModelSpec] = {s.name: s for s in (PAPER_SVM, SVM, MLP, RF, GBT, GBT_KEYPOINTS)}
