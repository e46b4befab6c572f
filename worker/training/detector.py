"""The emergency detector as a scikit-learn estimator: grid search, threshold and delay.

`EmergencyDetector.fit(X, y, groups)` searches its spec's grid with GridSearchCV, each
configuration evaluated by cross-validation over grouped inner folds of whole sequences
(worker.training.splits.grouped_folds); the winner's inner out-of-fold scores choose the threshold
and the delay (worker.training.selection.choose_operating_point); the winner is then refitted on
every trainable frame.

Every family of worker.training.estimators runs here, the window model (`tcn`) too, so threshold
and delay are chosen in this one place. A window model scores a frame on the frames before it in
its stream: its inner folds fit on every frame of their training sequences (frames not to train
on get class index -1 and stay as context), every `max(stride, its own stride)`-th trainable
frame trained on, and it is refitted on every frame of X at its own stride (every other frame:
30 frames/s are redundant for a window).

Configurations are ranked by the average precision of Emergency over the POOLED inner
out-of-fold scores, not by the mean of per-fold average precisions: a per-split score cannot
express a pooled one, so GridSearchCV's unit of evaluation is a configuration's whole inner
cross-validation (`InnerCrossValidation`, one split holding every row), whose score is the pooled
average precision. GridSearchCV dispatches one task per configuration, on whatever joblib backend
is active (worker.grid.GridBackend: Dask when VIGIL_DASK_SCHEDULER is set).

GridSearchCV does not refit: the winner's inner out-of-fold scores are those its search task
computed (`WinnerScores` keeps the best configuration's scores when the search runs in this
process), so the winner's inner cross-validation runs once. Only when the search ran in other
processes (Dask, loky) is it run again here, with the same folds and seeds, to the same scores.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, MetaEstimatorMixin, clone
from sklearn.metrics import average_precision_score
from sklearn.model_selection import GridSearchCV
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.features import FEATURE_SETS
from vigil.policy import raw_decisions
from worker.training.data import FrameData
from worker.training.estimators import ModelSpec, fit_pipeline, positive_scores, takes_streams
from worker.training.selection import StreamScores, choose_operating_point
from worker.training.splits import grouped_folds


class InnerCrossValidation(MetaEstimatorMixin, BaseEstimator):
    """One configuration's inner cross-validation as an estimator.

    fit(X, y) fits a clone of `estimator` on each fold's training rows and keeps every row's
    out-of-fold scores (`oof_scores_`; the folds' test rows partition X) and the average precision
    of class `positive` over the pooled out-of-fold scores of the scored rows (y >= 0):
    `average_precision_`. `fit_target`, if given, is what the folds' models are fitted to
    (y otherwise); `streams`, each row's stream, is passed to a model that takes streams."""

    def __init__(self, estimator, folds, positive: int = 1) -> None:
        self.estimator = estimator
        self.folds = folds
        self.positive = positive

    def fit(self, X, y, fit_target=None, streams=None):
        X, y = np.asarray(X), np.asarray(y)
        fit_target = y if fit_target is None else np.asarray(fit_target)
        scores = None
        for train, test in self.folds:
            fitted = fit_pipeline(
                clone(self.estimator), X[train], fit_target[train], _rows(streams, train)
            )
            fold_scores = positive_scores(fitted, X[test], _rows(streams, test))
            if scores is None:
                scores = np.zeros((len(X), fold_scores.shape[1]))
            scores[test] = fold_scores
        self.oof_scores_ = scores
        self.average_precision_ = pooled_average_precision_of(y, scores, self.positive)
        return self


def _rows(values, rows):
    return None if values is None else np.asarray(values)[rows]


def pooled_average_precision_of(y: np.ndarray, scores: np.ndarray, positive: int) -> float:
    """Average precision of class `positive` over the scored rows (y >= 0)."""
    scored = y >= 0
    return float(average_precision_score(y[scored] == positive, scores[scored, positive]))


def pooled_average_precision(estimator: InnerCrossValidation, X, y) -> float:
    """GridSearchCV's scorer: the pooled out-of-fold average precision the fit computed."""
    return estimator.average_precision_


class WinnerScores:
    """GridSearchCV's scorer that also keeps the out-of-fold scores of the best configuration
    it has scored (the first of equals, as GridSearchCV's `best_index_` picks), keyed by its
    grid parameters. Scorers that run in other processes keep nothing here."""

    def __init__(self, keys: list[str]) -> None:
        self.keys = keys
        self.best: tuple[float, dict, np.ndarray] | None = None

    def __call__(self, estimator: InnerCrossValidation, X, y) -> float:
        score = pooled_average_precision(estimator, X, y)
        if self.best is None or score > self.best[0]:
            params = estimator.get_params(deep=True)
            self.best = (score, {k: params[k] for k in self.keys}, estimator.oof_scores_)
        return score

    def scores_of(self, params: dict) -> np.ndarray | None:
        """The kept out-of-fold scores if they are those of `params`, else None."""
        if self.best is not None and self.best[1] == params:
            return self.best[2]
        return None


class EmergencyDetector(ClassifierMixin, BaseEstimator):
    """Frame classifier with its operating point, chosen on training sequences only.

    fit(X, y, groups): X holds the full feature vectors (vigil.features.FEATURE_NAMES) of whole
    sequences' frames (feature_set None: X's columns are the features), y each frame's class
    index in MODE_CLASSES[mode] (-1: unlabelled), groups its sequence (None: every frame is a
    sequence of its own). Metadata: `timestamps` (s, for the delay; default 30 frames/s),
    `usable` (a pose was seen; only usable labelled frames are fitted and ranked), `fit_target`
    (what the models are fitted to, default y) and `positive_sequence` (per frame, whether its
    sequence is a fall; default: it has an Emergency frame). Frames of a sequence are in time
    order (a window model's windows are the frames before each in its sequence).

    Learned: `model_` (the refitted pipeline), `threshold_`, `delay_s_`, `columns_`,
    `best_params_` (grid keys), `cv_results_` (GridSearchCV's), `grid_scores_`,
    `oof_scores_` (the winner's inner out-of-fold scores, frames in X order), `delay_sweep_`.
    """

    def __init__(
        self,
        family: str = "rf",
        grid: dict[str, list[Any]] | None = None,
        fixed: dict[str, Any] | None = None,
        feature_set: str | None = "full",
        operating_point: str = "event",
        mode: str = "walking",
        n_inner: int = 4,
        stride: int = 2,
        seed: int = 0,
        n_jobs: int | None = None,
    ) -> None:
        self.family, self.grid, self.fixed = family, grid, fixed
        self.feature_set, self.operating_point, self.mode = feature_set, operating_point, mode
        self.n_inner, self.stride, self.seed, self.n_jobs = n_inner, stride, seed, n_jobs

    @classmethod
    def from_spec(cls, spec: ModelSpec, **params) -> EmergencyDetector:
        return cls(
            spec.family, spec.grid, spec.fixed, spec.feature_set, spec.operating_point, **params
        )

    def fit(
        self,
        X,
        y,
        groups=None,
        *,
        timestamps=None,
        usable=None,
        fit_target=None,
        positive_sequence=None,
    ):
        start = time.perf_counter()
        X, y = validate_data(self, X, y)
        spec = ModelSpec(
            "",
            self.family,
            self.grid or {},
            self.feature_set or "full",
            fixed=self.fixed or {},
            operating_point=self.operating_point,
        )
        classes = MODE_CLASSES[TransportMode(self.mode)]
        e = classes.index(Decision.EMERGENCY)
        check_classification_targets(y)
        y = y.astype(np.int64)
        if not ((y == e).any() and ((y >= 0) & (y != e)).any()):
            raise ValueError(
                "y holds only one class: an emergency detector needs Emergency frames and "
                "frames of another class to choose its threshold"
            )
        n = len(y)
        groups = np.arange(n) if groups is None else np.asarray(groups)
        sequence_ids, group = np.unique(groups, return_inverse=True)  # sequences in sorted order
        timestamps = np.arange(n) / 30.0 if timestamps is None else np.asarray(timestamps)
        usable = np.ones(n, bool) if usable is None else np.asarray(usable, bool)
        trainable = (y >= 0) & usable
        # frames not to fit on (unlabelled, or no pose seen) are class -1: a per-frame model never
        # sees them, a window model keeps them as context
        fit_target = np.where(trainable, y if fit_target is None else np.asarray(fit_target), -1)
        if positive_sequence is None:
            positive_sequence = y == e
        is_positive = np.zeros(len(sequence_ids), bool)
        np.logical_or.at(is_positive, group, np.asarray(positive_sequence, bool))

        self.columns_ = (
            np.arange(X.shape[1]) if self.feature_set is None else FEATURE_SETS[self.feature_set]
        )
        self.classes_ = np.arange(len(classes))
        features = X[:, self.columns_]
        everything = np.arange(n)
        n_features = len(self.columns_)
        model = spec.pipeline(n_features, self.seed)
        streams = takes_streams(model)
        inner_model = model
        if streams:
            model.set_params(model__n_classes=len(classes))
            stride = max(self.stride, model.get_params()["model__stride"])
            inner_model = clone(model).set_params(model__stride=stride)
        folds = []
        for inner_train, inner_test in grouped_folds(is_positive, self.n_inner, self.seed):
            in_train = np.isin(group, inner_train)
            # a window model fits on whole sequences (its stride picks the frames trained on),
            # the others on every `stride`-th trainable frame
            train = (
                np.flatnonzero(in_train)
                if streams
                else np.flatnonzero(in_train & trainable)[:: self.stride]
            )
            folds.append((train, np.flatnonzero(np.isin(group, inner_test))))
        inner_cv = InnerCrossValidation(inner_model, folds, e)
        param_grid = [
            {f"estimator__{key}": values for key, values in point.items()}
            for point in spec.param_grid(n_features)
        ]
        scorer = WinnerScores(sorted({key for point in param_grid for key in point}))
        search = GridSearchCV(
            inner_cv,
            param_grid,
            scoring=scorer,
            cv=[(everything, everything)],
            refit=False,
            n_jobs=self.n_jobs,
            error_score="raise",
        )
        scored_y = np.where(usable, y, -1)
        search.fit(features, scored_y, fit_target=fit_target, streams=group)
        configurations = spec.configurations()
        self.cv_results_ = search.cv_results_
        self.best_params_ = configurations[search.best_index_]
        self.grid_scores_ = [
            {"params": jsonable(params), "average_precision": float(score)}
            for params, score in zip(
                configurations, search.cv_results_["mean_test_score"], strict=True
            )
        ]
        winner = clone(inner_cv).set_params(**search.best_params_)
        self.oof_scores_ = scorer.scores_of(search.best_params_)
        if self.oof_scores_ is None:  # the search ran in other processes
            self.oof_scores_ = winner.fit(
                features, scored_y, fit_target=fit_target, streams=group
            ).oof_scores_

        frames = FrameData(
            names=[str(s) for s in sequence_ids],
            is_positive_sequence=is_positive,
            features=features,
            target=y,
            group=group,
            timestamps=timestamps,
            usable=usable,
            mode=TransportMode(self.mode),
            data_sha256="",
        )
        stream = StreamScores(frames, np.arange(len(sequence_ids)), self.oof_scores_)
        labelled = y >= 0
        self.threshold_, self.delay_s_, self.delay_sweep_ = choose_operating_point(
            stream, self.oof_scores_[labelled], y[labelled], spec.operating_point
        )
        best = {
            key.removeprefix("estimator__"): value for key, value in search.best_params_.items()
        }
        final = clone(model).set_params(**best)
        fitted_rows = everything if streams else np.flatnonzero(trainable)
        self.model_ = fit_pipeline(
            final, features[fitted_rows], fit_target[fitted_rows], group[fitted_rows]
        )
        self.seconds_ = time.perf_counter() - start
        return self

    def predict_proba(self, X, groups=None) -> np.ndarray:
        """(n, k) class scores of full feature vectors, as the exported ONNX graph gives them
        (`groups`: each frame's sequence, for a window model; None: one sequence)."""
        check_is_fitted(self, "model_")
        X = validate_data(self, X, reset=False)
        return positive_scores(self.model_, X[:, self.columns_], groups)

    def predict(self, X, groups=None) -> np.ndarray:
        """Class index per frame at the chosen threshold, before the delay filter (frames
        alone carry no time)."""
        classes = MODE_CLASSES[TransportMode(self.mode)]
        return raw_decisions(self.predict_proba(X, groups), classes, self.threshold_)


def fit_on(detector: EmergencyDetector, data: FrameData, sequences: np.ndarray):
    """Fit `detector` on every frame of `sequences` of `data` (frames in data order)."""
    mask = data.frames_of(sequences)
    return detector.fit(
        data.features[mask],
        data.target[mask],
        data.group[mask],
        timestamps=data.timestamps[mask],
        usable=data.usable[mask],
        fit_target=data.fit_target[mask],
        positive_sequence=data.is_positive_sequence[data.group[mask]],
    )


def jsonable(params: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in params.items()}
