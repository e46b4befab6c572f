"""The model families and the emergency detector as scikit-learn estimators."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.utils.estimator_checks import check_estimator

from worker.training.cross_validation import select
from worker.training.data import from_urfd
from worker.training.detector import EmergencyDetector, InnerCrossValidation, WinnerScores, fit_on
from worker.training.estimators import FAMILIES, ModelSpec
from worker.training.trainers import SklearnTrainer

NAMES = [f"fall-{i:02d}" for i in range(1, 5)] + [f"adl-{i:02d}" for i in range(1, 5)]
TINY_GBT = ModelSpec(
    "gbt-tiny", "gbt", {"max_iter": [10, 30], "learning_rate": [0.1], "max_leaf_nodes": [7]}
)


PIPELINE_FITS_STEPS_IN_PLACE = (
    "a Pipeline fits its steps in place, so its `steps` parameter "
    "changes during fit (scikit-learn's Pipeline; GridSearchCV clones it per candidate and fold)"
)
#: Per family, the checks its pipeline fails on purpose.
FAMILY_DIFFERS = {
    "svm": {},
    "mlp": {
        "check_estimators_nan_inf": "early stopping holds out a validation set the check's tiny "
        "data cannot supply, so fit fails on that first",
        "check_classifiers_one_label": "early stopping's stratified validation split needs two "
        "classes",
        "check_classifiers_train": "80 iterations with early stopping on the check's few samples "
        "stay below its accuracy bar",
        "check_fit2d_1feature": "early stopping's validation split fails first, with its own "
        "message",
    },
    "rf": {"check_estimators_nan_inf": "random forests accept missing values (NaN) by design"},
    "gbt": {
        "check_estimators_nan_inf": "histogram boosting accepts missing values (NaN) by design"
    },
    # the window model scores each frame on the frames before it (tests/worker/test_temporal.py)
    "tcn": {
        "check_classifiers_train": "two epochs on the check's few samples stay below its "
        "accuracy bar",
        "check_classifiers_classes": "y holds class indices of a transport mode by design",
        "check_methods_sample_order_invariance": "reordering the frames changes each frame's "
        "window by design",
        "check_methods_subset_invariance": "a subset of the frames holds other windows by design",
    },
}
#: Fewer trees and iterations than the grids use: the checks test the API, not the fit quality.
SMALL = {
    "svm": {},
    "mlp": {},
    "rf": {"model__n_estimators": 10, "model__n_jobs": 1},
    "gbt": {"model__max_iter": 10},
    "tcn": {
        "model__window": 3,
        "model__channels": 4,
        "model__epochs": 2,
        "model__batch_size": 32,
        "model__stride": 1,
    },
}
#: Checks scikit-learn itself reports as not applicable here (it raises SkipTest inside them).
#: Anything else that is skipped fails the test.
NOT_APPLICABLE = (
    "SCIPY_ARRAY_API is not set",  # array API inputs: Vigil's arrays are numpy
    "pandas is not installed",  # Vigil passes numpy arrays, never data frames
    "does not have a decision_function method",  # the tree and MLP pipelines score by proba
)


def run_checks(estimator, expected_failed_checks: dict[str, str]) -> list[dict]:
    results = check_estimator(
        estimator, expected_failed_checks=expected_failed_checks, on_skip=None, on_fail=None
    )
    failed = [(r["check_name"], repr(r["exception"])) for r in results if r["status"] == "failed"]
    assert failed == []
    skipped = [(r["check_name"], str(r["exception"])) for r in results if r["status"] == "skipped"]
    assert [s for s in skipped if not any(n in s[1] for n in NOT_APPLICABLE)] == []
    return results


@pytest.mark.parametrize("family", list(FAMILIES))
def test_family_pipelines_are_scikit_learn_estimators(family):
    differs = {
        "check_estimators_overwrite_params": PIPELINE_FITS_STEPS_IN_PLACE,
        "check_dont_overwrite_parameters": PIPELINE_FITS_STEPS_IN_PLACE,
        **FAMILY_DIFFERS[family],
    }
    results = run_checks(FAMILIES[family](0).set_params(**SMALL[family]), differs)
    passed = {r["check_name"] for r in results if r["status"] == "passed"}
    assert {"check_fit_idempotent", "check_classifiers_classes"} - set(differs) <= passed
    # a check expected to fail that passes would be reported as failed above ("xpass")
    assert {r["check_name"] for r in results if r["status"] == "xfail"} == set(differs)


#: What EmergencyDetector does differently from a plain classifier, on purpose.
DETECTOR_DIFFERS = {
    "check_classifiers_classes": "y holds class indices into the transport mode's classes, not "
    "arbitrary labels",
    "check_classifiers_train": "predict gives decisions at the operating point chosen for alarms "
    "(Youden's J / event F1 over sequences), not the most accurate labels; walking mode has two "
    "classes",
    "check_fit2d_1sample": "one sample cannot be split into grouped inner folds; the error says "
    "so in other words",
}


def test_emergency_detector_is_a_scikit_learn_estimator():
    detector = EmergencyDetector(
        "rf", {"n_estimators": [5]}, {"n_jobs": 1}, None, "youden", n_inner=2
    )
    results = run_checks(detector, DETECTOR_DIFFERS)
    passed = {r["check_name"] for r in results if r["status"] == "passed"}
    assert {"check_fit_idempotent", "check_no_attributes_set_in_init"} <= passed


def test_unknown_family_is_refused():
    with pytest.raises(ValueError, match="unknown family 'knn'"):
        ModelSpec("x", "knn", {}).pipeline(10)


@pytest.fixture(scope="module")
def data():
    return from_urfd(names=NAMES)


@pytest.fixture(scope="module")
def fitted(data):
    detector = EmergencyDetector.from_spec(TINY_GBT, n_inner=3, stride=3)
    return detector, fit_on(detector, data, np.arange(len(NAMES)))


def test_fit_returns_self_with_the_operating_point_chosen_on_inner_folds(data, fitted):
    detector, returned = fitted
    assert returned is detector
    assert detector.best_params_ in TINY_GBT.configurations()
    assert 0 < detector.threshold_ < 1 and 0 <= detector.delay_s_ <= 1.5
    assert list(detector.columns_) == list(range(data.features.shape[1]))
    # GridSearchCV's results rank the configurations by pooled out-of-fold average precision
    scores = detector.cv_results_["mean_test_score"]
    assert detector.cv_results_["rank_test_score"][np.argmax(scores)] == 1
    assert [g["average_precision"] for g in detector.grid_scores_] == scores.tolist()
    assert detector.best_params_ == TINY_GBT.configurations()[int(np.argmax(scores))]
    # the refitted model scores the frames as predict_proba does
    frames = data.features[:50]
    np.testing.assert_array_equal(
        detector.predict_proba(frames), detector.model_.predict_proba(frames)
    )
    assert set(detector.predict(frames)) <= {0, 1}
    # params live in __init__ only: a clone is unfitted and fits to the same result
    again = fit_on(clone(detector), data, np.arange(len(NAMES)))
    assert again.threshold_ == detector.threshold_ and again.delay_s_ == detector.delay_s_
    np.testing.assert_array_equal(again.oof_scores_, detector.oof_scores_)


def test_select_uses_the_detector_and_its_pooled_out_of_fold_scores(data, fitted):
    sequences = np.arange(len(NAMES))
    selected = select(SklearnTrainer(TINY_GBT), data, sequences, n_inner=3, stride=3)
    detector, _ = fitted
    assert selected.params == detector.best_params_
    assert (selected.threshold, selected.delay_s) == (detector.threshold_, detector.delay_s_)
    np.testing.assert_array_equal(selected.oof.scores, detector.oof_scores_)
    assert len(selected.oof.scores) == int(data.frames_of(sequences).sum())


def test_the_winners_inner_cross_validation_runs_once(data, fitted, monkeypatch):
    """The search's own out-of-fold scores of the winner are kept: one inner cross-validation
    per configuration, none again for the winner (GridSearchCV's refit ran it twice)."""
    fits = []
    original = InnerCrossValidation.fit

    def counting_fit(self, X, y, **params):
        fits.append(self.get_params(deep=True)["estimator__model__max_iter"])
        return original(self, X, y, **params)

    monkeypatch.setattr(InnerCrossValidation, "fit", counting_fit)
    detector = fit_on(clone(fitted[0]), data, np.arange(len(NAMES)))
    assert sorted(fits) == sorted(c["max_iter"] for c in TINY_GBT.configurations())
    np.testing.assert_array_equal(detector.oof_scores_, fitted[0].oof_scores_)


def test_a_search_in_other_processes_recomputes_the_same_winner_scores(data, fitted, monkeypatch):
    """When the scorer ran elsewhere (Dask, loky) it kept nothing here: the winner's inner
    cross-validation runs again, to exactly the scores the search computed."""
    monkeypatch.setattr(WinnerScores, "scores_of", lambda self, params: None)
    detector = fit_on(clone(fitted[0]), data, np.arange(len(NAMES)))
    assert detector.best_params_ == fitted[0].best_params_
    np.testing.assert_array_equal(detector.oof_scores_, fitted[0].oof_scores_)
    assert (detector.threshold_, detector.delay_s_) == (fitted[0].threshold_, fitted[0].delay_s_)
