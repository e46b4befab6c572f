"""Grid search scale-out: every configuration's inner cross-validation is one task, run on a Dask
cluster through joblib's dask backend when a scheduler address is set, else in local processes.

The detection code's `select` then re-runs only the winning configuration to choose threshold
and delay and to refit, so the science (folds, scoring, operating point) stays in one place.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from joblib import Parallel, delayed, parallel_backend
from sklearn.metrics import average_precision_score

from vigil.classes import Decision
from worker.training.cross_validation import Selected, _jsonable, _oof_scores, select
from worker.training.data import FrameData
from worker.training.splits import grouped_folds
from worker.training.trainers import Trainer


def configuration_score(
    trainer: Trainer, data: FrameData, sequences: np.ndarray, params: dict, n_inner: int,
    stride: int, seed: int,
) -> float:  # fmt: skip
    """Average precision of Emergency on inner out-of-fold scores (as `select` ranks them)."""
    folds = grouped_folds(data.is_positive_sequence[sequences], n_inner, seed)
    oof = _oof_scores(trainer, data, sequences, params, folds, stride)
    mask = data.frames_of(sequences)
    target, ok = data.target[mask], (data.target[mask] >= 0) & data.usable[mask]
    e = data.classes.index(Decision.EMERGENCY)
    return float(average_precision_score(target[ok] == e, oof.scores[ok, e]))


class _Fixed:
    """The trainer with its grid narrowed to one configuration."""

    def __init__(self, trainer: Trainer, params: dict) -> None:
        self._trainer, self._params = trainer, params

    def configurations(self) -> list[dict[str, Any]]:
        return [self._params]

    def __getattr__(self, name):
        return getattr(self._trainer, name)


@dataclass
class GridBackend:
    scheduler: str | None = None
    n_jobs: int = 1

    @property
    def description(self) -> str:
        return f"dask cluster at {self.scheduler}" if self.scheduler else f"{self.n_jobs} local"


def grid_select(
    trainer: Trainer, data: FrameData, sequences: np.ndarray, backend: GridBackend,
    n_inner: int = 4, stride: int = 2, seed: int = 0, on_config=None,
) -> Selected:  # fmt: skip
    sequences = np.sort(np.asarray(sequences))
    configurations = trainer.configurations()
    if len(configurations) == 1 and backend.scheduler is None:
        return select(trainer, data, sequences, n_inner, stride, seed)
    client = None
    if backend.scheduler:
        from distributed import Client

        client = Client(backend.scheduler, timeout="10s", set_as_default=False)
        context = parallel_backend("dask", client=client)
        n_jobs = -1
    else:
        context = nullcontext() if backend.n_jobs == 1 else parallel_backend("loky")
        n_jobs = backend.n_jobs
    try:
        with context:
            scores = []
            for score in Parallel(n_jobs=n_jobs, return_as="generator")(
                delayed(configuration_score)(trainer, data, sequences, p, n_inner, stride, seed)
                for p in configurations
            ):
                scores.append(score)
                if on_config is not None:
                    on_config(len(scores), len(configurations))
    finally:
        if client is not None:
            client.close()
    best = int(np.argmax(scores))
    selected = select(_Fixed(trainer, configurations[best]), data, sequences, n_inner, stride, seed)
    selected.grid_scores = [
        {"params": _jsonable(p), "average_precision": s}
        for p, s in zip(configurations, scores, strict=True)
    ]
    return selected
