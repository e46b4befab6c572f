"""Grid search, threshold and delay on training sequences only; evaluation on held-out ones.

For every outer fold, the grid is searched by inner cross-validation over the training sequences
(inner folds of whole sequences); the best configuration's inner out-of-fold scores choose the
threshold and the delay; the configuration is refitted on all training sequences and scored on the
held-out fold. The test fold never influences any choice. All of it is EmergencyDetector's fit
(worker.training.detector), for every model spec: `seed` here splits the outer folds, the
trainer's seed the inner ones.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from worker.training.data import FrameData
from worker.training.detector import fit_on
from worker.training.selection import StreamScores, evaluate_folds
from worker.training.splits import grouped_folds
from worker.training.trainers import SklearnTrainer


@dataclass
class Selected:
    params: dict[str, Any]
    threshold: float
    delay_s: float
    grid_scores: list[dict[str, Any]]
    delay_sweep: dict
    oof: StreamScores
    fitted: Any = None
    seconds: float = 0.0


def select(
    trainer: SklearnTrainer,
    data: FrameData,
    sequences: np.ndarray,
    n_inner: int = 4,
    stride: int = 2,
    progress=None,
    n_jobs: int | None = None,
) -> Selected:
    """Grid search + threshold + delay using only `sequences`, then a refit on them: the
    trainer's EmergencyDetector (GridSearchCV, on the active joblib backend), for every family,
    the window model too."""
    start = time.perf_counter()
    sequences = np.sort(np.asarray(sequences))
    detector = fit_on(trainer.detector(data.mode.value, n_inner, stride, n_jobs), data, sequences)
    if progress is not None:
        progress.update(len(detector.grid_scores_))
    return Selected(
        detector.best_params_,
        detector.threshold_,
        detector.delay_s_,
        detector.grid_scores_,
        detector.delay_sweep_,
        StreamScores(data, sequences, detector.oof_scores_),
        detector.model_,
        time.perf_counter() - start,
    )


@dataclass
class CrossValidation:
    name: str
    folds: list[Selected] = field(default_factory=list)
    test_scores: list[StreamScores] = field(default_factory=list)
    result: dict = field(default_factory=dict)
    seconds: float = 0.0


def outer_folds(
    is_positive_sequence: np.ndarray,
    n_folds: int,
    seed: int,
    train_only: np.ndarray | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(train, test) sequence indices of the outer folds; the `train_only` sequences are in
    every fold's training sequences and never held out (hard negatives from another source:
    the figures stay those of the other sequences, split as they would be without them)."""
    extra = np.asarray([] if train_only is None else train_only, np.int64)
    tested = np.setdiff1d(np.arange(len(is_positive_sequence)), extra)
    return [
        (np.concatenate([tested[train], extra]), tested[test])
        for train, test in grouped_folds(np.asarray(is_positive_sequence)[tested], n_folds, seed)
    ]


def cross_validate(
    trainer: SklearnTrainer,
    data: FrameData,
    n_folds: int = 5,
    n_inner: int = 4,
    stride: int = 2,
    seed: int = 0,
    progress=None,
    train_only: np.ndarray | None = None,
) -> CrossValidation:
    """`train_only`: see `outer_folds`."""
    start = time.perf_counter()
    cv = CrossValidation(trainer.name)
    for train, test in outer_folds(data.is_positive_sequence, n_folds, seed, train_only):
        selected = select(trainer, data, train, n_inner, stride, progress=progress)
        scores = trainer.score(selected.fitted, data, test)
        cv.folds.append(selected)
        cv.test_scores.append(StreamScores(data, np.sort(test), scores))
    cv.result = evaluate_folds(
        [
            (stream, sel.threshold, sel.delay_s)
            for stream, sel in zip(cv.test_scores, cv.folds, strict=True)
        ]
    )
    cv.seconds = time.perf_counter() - start
    return cv
