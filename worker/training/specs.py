"""The model-spec registry: every model spec by a unique name.

Everything that trains a model by name reads it here: `vigil-train train-default` (rf-default),
`python -m worker.bootstrap train-keypoints` (rf-keypoints-default, `make run`'s keypoints-only
walking model), the retrain job's `spec` parameter, `vigil-train train --models` and the
benchmarks in bench/. Registering a second spec under a name already taken raises
DuplicateSpecError: a name is what a model version, a benchmark result and a retrain job refer
to, so it must mean one configuration grid.

Names: `<family>[-<feature set>]` is the grid the benchmark searches (`make bench-detection`,
`benchmarked()`; `tcn` is the window model's one configuration); `-default` marks the one fixed
configuration `make run` trains (rf-default with floor measures, rf-keypoints-default without).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from worker.training.estimators import ModelSpec


class DuplicateSpecError(ValueError):
    """A model spec registered under a name another spec has."""


class SpecRegistry(Mapping[str, ModelSpec]):
    """Model specs by unique name, in registration order (a read-only mapping but for
    `register`)."""

    def __init__(self) -> None:
        self._specs: dict[str, ModelSpec] = {}
        self._benchmarked: list[str] = []

    def register(self, spec: ModelSpec, *, benchmarked: bool = False) -> ModelSpec:
        """Add `spec` (returned); `benchmarked`: one of the grids `make bench-detection`
        compares. A name already registered is refused, naming it and its spec."""
        if not spec.name:
            raise ValueError("a registered model spec needs a name")
        if spec.name in self._specs:
            taken = self._specs[spec.name]
            raise DuplicateSpecError(
                f"model spec name {spec.name!r} is taken (by {taken.family} on feature set "
                f"{taken.feature_set!r}, {len(taken.configurations())} configuration(s)): "
                "register the spec under another name"
            )
        self._specs[spec.name] = spec
        if benchmarked:
            self._benchmarked.append(spec.name)
        return spec

    def benchmarked(self) -> dict[str, ModelSpec]:
        """The specs `make bench-detection` compares, in registration order."""
        return {name: self._specs[name] for name in self._benchmarked}

    def __getitem__(self, name: str) -> ModelSpec:
        try:
            return self._specs[name]
        except KeyError:
            known = ", ".join(self._specs)
            raise KeyError(f"unknown model spec {name!r} (known: {known})") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._specs)

    def __len__(self) -> int:
        return len(self._specs)


#: The registry.
SPECS = SpecRegistry()

# --- the grids the benchmark compares ----------------------------------------------------------
PAPER_SVM = SPECS.register(
    ModelSpec(
        name="svm-paper",
        family="svm",
        grid={"degree": [2], "C": [0.5], "gamma_times_1_over_n": [1.0], "class_weight": [None]},
        feature_set="pose",
        operating_point="youden",
        description="Zachariae et al.: SVM, poly kernel degree 2, C=0.5, gamma=1/n_features, "
        "single-frame pose features",
    ),
    benchmarked=True,
)
SVM = SPECS.register(
    ModelSpec(
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
    ),
    benchmarked=True,
)
MLP = SPECS.register(
    ModelSpec(
        name="mlp",
        family="mlp",
        grid={
            "hidden_layer_sizes": [(64,), (128, 64)],
            "alpha": [1e-4, 1e-2],
            "learning_rate_init": [1e-3, 3e-3],
            "activation": ["relu", "tanh"],
        },
        description="MLP, pose + temporal features",
    ),
    benchmarked=True,
)
RF = SPECS.register(
    ModelSpec(
        name="rf",
        family="rf",
        grid={
            "n_estimators": [60, 150],
            "max_depth": [8, 16],
            "min_samples_leaf": [1, 5],
            "max_features": ["sqrt", 0.3],
        },
        description="Random forest, pose + temporal features",
    ),
    benchmarked=True,
)
GBT = SPECS.register(
    ModelSpec(
        name="gbt",
        family="gbt",
        grid={
            "max_iter": [100, 200],
            "learning_rate": [0.1],
            "max_leaf_nodes": [15, 31],
            "l2_regularization": [0.0, 1.0],
        },
        description="Gradient-boosted trees (histogram), pose, temporal and floor features",
    ),
    benchmarked=True,
)
GBT_KEYPOINTS = SPECS.register(
    ModelSpec(
        name="gbt-keypoints",
        family="gbt",
        grid=GBT.grid,
        feature_set="keypoints",
        description="Gradient-boosted trees without floor measures, for robots whose depth camera "
        "has no calibrated mount",
    ),
    benchmarked=True,
)
RF_KEYPOINTS = SPECS.register(
    ModelSpec(
        name="rf-keypoints",
        family="rf",
        grid=RF.grid,
        feature_set="keypoints",
        description="Random forest without floor measures, for robots whose depth camera has no "
        "calibrated mount",
    ),
    benchmarked=True,
)
#: The window model: a temporal 1D-CNN over the last 24 frames (worker.training.temporal); one
#: configuration, selected (inner cross-validation, threshold and delay) like every other grid.
TCN = SPECS.register(
    ModelSpec(
        name="tcn",
        family="tcn",
        grid={"window": [24], "channels": [48], "epochs": [10], "dropout": [0.2]},
        description="Temporal 1D-CNN over the last 24 frames of pose, temporal and floor features",
    ),
    benchmarked=True,
)

# --- the fixed configurations `make run` trains ------------------------------------------------

#: Name and configuration are a contract: worker jobs, bootstrap and bench/registry.py queue
#: retrains of "rf-default" and expect train-default to produce the same configuration.
DEFAULT = SPECS.register(
    ModelSpec(
        name="rf-default",
        family="rf",
        grid={
            "n_estimators": [100],
            "max_depth": [16],
            "min_samples_leaf": [5],
            "max_features": [0.3],
        },
        description="Default walking model: random forest on pose + temporal features",
    )
)
#: The walking mode's keypoints-only model (no floor measures): every walking robot's fallback
#: and the model of robots without a calibrated depth camera. A smaller forest than the default
#: keeps the first `make run` short. One configuration, apart from the benchmark's 16-point grid
#: on the same feature set (rf-keypoints).
KEYPOINTS_DEFAULT = SPECS.register(
    ModelSpec(
        name="rf-keypoints-default",
        family="rf",
        grid={
            "n_estimators": [60],
            "max_depth": [12],
            "min_samples_leaf": [5],
            "max_features": [0.3],
        },
        feature_set="keypoints",
        description="Keypoints-only walking model (no floor measures): every walking robot's "
        "fallback, and the model of robots whose camera has no known mount",
    )
)
