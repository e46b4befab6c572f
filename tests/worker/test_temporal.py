"""The temporal 1D-CNN (tcn) as a scikit-learn estimator, and its Trainer."""

from __future__ import annotations

import numpy as np
import onnxruntime
import pytest
from sklearn.base import clone
from sklearn.utils.estimator_checks import check_estimator

from worker.training.data import from_urfd
from worker.training.temporal import TemporalClassifier, TemporalTrainer

SMALL = {"window": 3, "channels": 4, "epochs": 2, "batch_size": 32, "stride": 1}
#: Checks TemporalClassifier fails on purpose.
DIFFERS = {
    "check_classifiers_train": "two epochs on the check's few samples stay below its accuracy "
    "bar (these checks test the API, not the fit quality)",
    "check_classifiers_classes": "y holds class indices of a transport mode "
    "(vigil.classes.MODE_CLASSES) by design, not arbitrary labels",
    "check_methods_sample_order_invariance": "a frame is scored on the frames before it in its "
    "stream: reordering the frames changes each frame's window by design",
    "check_methods_subset_invariance": "a frame is scored on the frames before it in its "
    "stream: a subset holds other windows by design",
}
NOT_APPLICABLE = (
    "SCIPY_ARRAY_API is not set",
    "pandas is not installed",
    "does not have a decision_function method",
)


def test_temporal_classifier_is_a_scikit_learn_estimator():
    results = check_estimator(
        TemporalClassifier(**SMALL), expected_failed_checks=DIFFERS, on_skip=None, on_fail=None
    )
    failed = [(r["check_name"], repr(r["exception"])) for r in results if r["status"] == "failed"]
    assert failed == []
    skipped = [str(r["exception"]) for r in results if r["status"] == "skipped"]
    assert [s for s in skipped if not any(n in s for n in NOT_APPLICABLE)] == []
    passed = {r["check_name"] for r in results if r["status"] == "passed"}
    assert {"check_no_attributes_set_in_init", "check_estimators_dtypes"} <= passed


def test_fit_returns_self_and_windows_stay_inside_their_stream():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(60, 5)).astype(np.float32)
    y = (X[:, 0] > 0).astype(int)
    groups = np.repeat([0, 1, 2], 20)
    classifier = TemporalClassifier(**SMALL)
    assert classifier.fit(X, y, groups) is classifier
    together = classifier.predict_proba(X, groups)
    alone = np.concatenate(
        [classifier.predict_proba(X[groups == g], groups[groups == g]) for g in range(3)]
    )
    np.testing.assert_allclose(together, alone, rtol=0, atol=1e-6)
    # without groups the frames are one stream: the second stream's first frames see the first's
    assert not np.allclose(classifier.predict_proba(X)[20:22], together[20:22])
    # a negative class index is context only, never trained on
    masked = np.where(np.arange(60) % 2 == 0, y, -1)
    again = clone(classifier).fit(X, masked, groups)
    assert again.classes_.tolist() == [0, 1]
    with pytest.raises(ValueError, match="one class"):
        clone(classifier).fit(X, np.zeros(60, int), groups)


def test_n_classes_fixes_the_outputs_even_when_a_class_is_absent():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(40, 4)).astype(np.float32)
    y = (X[:, 1] > 0).astype(int)  # classes 0 and 1 of a mode with three
    classifier = TemporalClassifier(**SMALL, n_classes=3).fit(X, y)
    assert classifier.predict_proba(X).shape == (40, 3)


@pytest.fixture(scope="module")
def urfd():
    return from_urfd(names=["fall-01", "fall-02", "adl-01", "adl-02"])


def test_trainer_exports_the_classifier_it_fits(urfd):
    trainer = TemporalTrainer(window=8, channels=8, epochs=1)
    (params,) = trainer.configurations()
    fitted = trainer.fit(urfd, np.array([0, 2]), params, 2)
    assert isinstance(fitted, TemporalClassifier)
    scores = trainer.score(fitted, urfd, np.array([1, 3]))
    assert scores.shape == (int(urfd.frames_of(np.array([1, 3])).sum()), len(urfd.classes))
    windows, reference = trainer.reference(fitted, urfd, 32)
    session = onnxruntime.InferenceSession(trainer.to_onnx(fitted, urfd))
    (onnx_scores,) = session.run(None, {"windows": windows})
    np.testing.assert_allclose(onnx_scores, reference, rtol=0, atol=1e-5)
