"""The temporal 1D-CNN (tcn) as a scikit-learn estimator, and as a model family selected by
EmergencyDetector like the others (one selection path: threshold and delay chosen once, there)."""

from __future__ import annotations

import inspect
import sys

import numpy as np
import onnxruntime
import pytest
from sklearn.base import clone
from sklearn.utils.estimator_checks import check_estimator

from vigil.features import FEATURE_SETS
from vigil.runtime import FrameClassifier
from worker.training import cross_validation
from worker.training import detector as detector_module
from worker.training.cross_validation import select
from worker.training.data import from_urfd
from worker.training.detector import EmergencyDetector
from worker.training.estimators import ModelSpec, takes_streams
from worker.training.publish import publish
from worker.training.robot_path import replay_stream
from worker.training.selection import StreamScores, choose_operating_point
from worker.training.specs import SPECS
from worker.training.splits import grouped_folds
from worker.training.temporal import TemporalClassifier, to_onnx
from worker.training.trainers import SklearnTrainer

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


#: The window model's spec, small: one configuration, as the registered `tcn` has.
TINY_TCN = ModelSpec("tcn-tiny", "tcn", {"window": [8], "channels": [8], "epochs": [1]})
N_INNER, STRIDE = 2, 3


def test_the_window_model_is_a_registered_spec_of_its_own_family():
    spec = SPECS["tcn"]
    assert spec.family == "tcn" and spec.feature_set == "full"
    assert spec.configurations() == [{"window": 24, "channels": 48, "epochs": 10, "dropout": 0.2}]
    model = spec.pipeline(len(FEATURE_SETS["full"]))
    assert takes_streams(model) and isinstance(model.steps[-1][1], TemporalClassifier)
    assert not takes_streams(SPECS["rf"].pipeline(len(FEATURE_SETS["full"])))
    assert "tcn" in SPECS.benchmarked()


@pytest.fixture(scope="module")
def urfd():
    return from_urfd(names=["fall-01", "fall-02", "adl-01", "adl-02"])


@pytest.fixture(scope="module")
def through_the_detector(urfd):
    """The tiny window model selected by select() (EmergencyDetector), with every call of
    choose_operating_point in any loaded worker module recorded."""
    calls = []

    def spy(*args, **kwargs):
        chosen = choose_operating_point(*args, **kwargs)
        calls.append((inspect.stack()[1].filename, chosen))
        return chosen

    holders = [
        module
        for name, module in list(sys.modules.items())
        if name.startswith("worker")
        and getattr(module, "choose_operating_point", None) is choose_operating_point
    ]
    with pytest.MonkeyPatch.context() as patch:
        for module in holders:
            patch.setattr(module, "choose_operating_point", spy)
        trainer = SklearnTrainer(TINY_TCN)
        selected = select(trainer, urfd, np.arange(4), n_inner=N_INNER, stride=STRIDE)
    return trainer, selected, calls


def test_threshold_and_delay_are_chosen_once_by_the_detector(through_the_detector):
    _, selected, calls = through_the_detector
    assert len(calls) == 1
    (caller, chosen) = calls[0]
    assert caller == detector_module.__file__
    assert (selected.threshold, selected.delay_s) == chosen[:2]
    assert selected.params == {"window": 8, "channels": 8, "epochs": 1}
    assert [g["params"] for g in selected.grid_scores] == [selected.params]
    # no second selection path is left beside the detector's
    assert not hasattr(cross_validation, "choose_operating_point")
    assert not hasattr(cross_validation, "_oof_scores")


def direct(stride: int = 2) -> TemporalClassifier:
    return TemporalClassifier(window=8, channels=8, epochs=1, n_classes=2, stride=stride, seed=0)


def direct_frames(data, sequences):
    """Features, training target (-1 where not trainable) and streams of `sequences`."""
    mask = data.frames_of(sequences)
    target = np.where(data.trainable[mask], data.fit_target[mask], -1)
    return data.features[mask], target, data.group[mask]


def test_the_detector_trains_and_scores_as_the_classifier_fitted_directly(
    urfd, through_the_detector
):
    trainer, selected, _ = through_the_detector
    sequences = np.arange(4)
    X, target, groups = direct_frames(urfd, sequences)
    fitted = direct().fit(X, target, groups)
    model = selected.fitted.steps[-1][1]
    assert model.get_params() == fitted.get_params()
    np.testing.assert_array_equal(
        trainer.score(selected.fitted, urfd, sequences), fitted.predict_proba(X, groups)
    )
    assert trainer.to_onnx(selected.fitted, urfd) == to_onnx(fitted)  # the same ONNX graph
    assert trainer.window_of(selected.fitted) == 8

    # The inner folds: each fitted directly on its training sequences' frames (every 3rd
    # trainable frame, the detector's stride), scored on its test sequences; their pooled
    # scores choose the operating point.
    oof = np.zeros((len(X), 2))
    for inner_train, inner_test in grouped_folds(urfd.is_positive_sequence, N_INNER, 0):
        Xi, ti, gi = direct_frames(urfd, inner_train)
        fold = direct(stride=STRIDE).fit(Xi, ti, gi)
        rows = np.isin(groups, inner_test)
        oof[rows] = fold.predict_proba(X[rows], groups[rows])
    np.testing.assert_array_equal(selected.oof.scores, oof)
    labelled = urfd.target >= 0
    threshold, delay_s, _ = choose_operating_point(
        StreamScores(urfd, sequences, oof), oof[labelled], urfd.target[labelled], "event"
    )
    assert (selected.threshold, selected.delay_s) == (threshold, delay_s)


def test_the_published_window_model_scores_the_same_on_the_robot(
    urfd, through_the_detector, tmp_path
):
    trainer, selected, _ = through_the_detector
    manifest = publish(trainer, selected, urfd, tmp_path / "tcn", version="tcn-tiny-1")
    assert manifest.window == 8 and manifest.threshold == selected.threshold
    assert manifest.delay_ms == round(selected.delay_s * 1000)
    session = onnxruntime.InferenceSession(tmp_path.joinpath("tcn", "model.onnx").read_bytes())
    assert session.get_inputs()[0].shape[1:] == [8, len(FEATURE_SETS["full"])]
    robot, dropped, _ = replay_stream(FrameClassifier.from_dir(tmp_path / "tcn"), urfd)
    assert dropped == 0
    np.testing.assert_allclose(
        robot.scores, trainer.score(selected.fitted, urfd, np.arange(4)), rtol=0, atol=1e-5
    )


def test_a_window_model_in_the_detector_has_every_class_of_its_mode():
    """Wheelchair mode has three classes; Pause frames are absent from these sequences, and the
    window model still gives three outputs, each frame scored on its own sequence's frames."""
    rng = np.random.default_rng(2)
    groups = np.repeat(np.arange(6), 30)
    X = rng.normal(size=(len(groups), 5))
    y = np.where((groups < 3) & (np.arange(len(groups)) % 30 >= 15), 1, 0)  # Emergency in 0-2
    X[:, 0] += 2.0 * y
    detector = EmergencyDetector(
        "tcn",
        {"window": [3], "channels": [4], "epochs": [2]},
        {"batch_size": 16},
        None,
        mode="wheelchair",
        n_inner=2,
    )
    assert detector.fit(X, y, groups) is detector
    assert detector.model_.steps[-1][1].n_classes == 3 and detector.oof_scores_.shape == (180, 3)
    scores = detector.predict_proba(X, groups)
    assert scores.shape == (180, 3)
    alone = detector.predict_proba(X[groups == 4], groups[groups == 4])
    np.testing.assert_allclose(scores[groups == 4], alone, rtol=0, atol=1e-6)
    assert 0 < detector.threshold_ < 1 and set(detector.predict(X, groups)) <= {0, 1, 2}
