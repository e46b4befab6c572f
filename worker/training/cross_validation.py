"""Grid search, threshold and delay on training sequences only; evaluation on held-out ones.

For every outer fold, the grid is searched by inner cross-validation over the training sequences
(inner folds of whole sequences); the best configuration's inner out-of-fold scores choose the
threshold and the delay; the configuration is refitted on all training sequences and scored on the
held-out fold. The test fold never influences any choice.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vigil.classes import Decision
from worker.training.data import FrameData
from worker.training.detector import fit_on, jsonable, pooled_average_precision_of
from worker.training.selection import (
    StreamScores,
    choose_operating_point,
    evaluate_folds,
)
from worker.training.splits import grouped_folds
from worker.training.trainers import SklearnTrainer, Trainer


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


def _oof_scores(
    trainer, data: FrameData, sequences: np.ndarray, params: dict, folds, stride: int
) -> StreamScores:
    mask = data.frames_of(sequences)
    scores = np.zeros((int(mask.sum()), len(data.classes)))
    group = data.group[mask]
    for inner_train, inner_test in folds:
        fitted = trainer.fit(data, sequences[inner_train], params, stride)
        rows = np.isin(group, sequences[inner_test])
        scores[rows] = trainer.score(fitted, data, sequences[inner_test])
    return StreamScores(data, np.sort(sequences), scores)


def select(
    trainer: Trainer,
    data: FrameData,
    sequences: np.ndarray,
    n_inner: int = 4,
    stride: int = 2,
    seed: int = 0,
    progress=None,
    n_jobs: int | None = None,
) -> Selected:
    """Grid search + threshold + delay using only `sequences`, then a refit on them.

    scikit-learn families: EmergencyDetector (GridSearchCV, on the active joblib backend).
    Window models (TemporalTrainer) have one configuration: its inner out-of-fold scores choose
    threshold and delay the same way."""
    start = time.perf_counter()
    sequences = np.sort(np.asarray(sequences))
    if isinstance(trainer, SklearnTrainer):
        detector = fit_on(
            trainer.detector(data.mode.value, n_inner, stride, n_jobs), data, sequences
        )
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
    (params,) = trainer.configurations()
    folds = grouped_folds(data.is_positive_sequence[sequences], n_inner, seed)
    oof = _oof_scores(trainer, data, sequences, params, folds, stride)
    if progress is not None:
        progress.update(1)
    mask = data.frames_of(sequences)
    target = data.target[mask]
    e = data.classes.index(Decision.EMERGENCY)
    ap = pooled_average_precision_of(np.where(data.usable[mask], target, -1), oof.scores, e)
    labelled = target >= 0
    threshold, delay_s, sweep = choose_operating_point(
        oof, oof.scores[labelled], target[labelled], trainer.operating_point
    )
    fitted = trainer.fit(data, sequences, params, 1)
    grid_scores = [{"params": jsonable(params), "average_precision": ap}]
    return Selected(
        params, threshold, delay_s, grid_scores, sweep, oof, fitted, time.perf_counter() - start
    )


@dataclass
class CrossValidation:
    name: str
    folds: list[Selected] = field(default_factory=list)
    test_scores: list[StreamScores] = field(default_factory=list)
    result: dict = field(default_factory=dict)
    seconds: float = 0.0


def cross_validate(
    trainer: Trainer,
    data: FrameData,
    n_folds: int = 5,
    n_inner: int = 4,
    stride: int = 2,
    seed: int = 0,
    progress=None,
) -> CrossValidation:
    start = time.perf_counter()
    cv = CrossValidation(trainer.name)
    for train, test in grouped_folds(data.is_positive_sequence, n_folds, seed):
        selected = select(trainer, data, train, n_inner, stride, seed, progress=progress)
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
