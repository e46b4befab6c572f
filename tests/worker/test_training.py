import numpy as np
import pytest

from vigil.classes import Decision
from vigil.features import extract_sequence
from vigil.model_file import load_classifier
from vigil.policy import apply_delay, raw_decisions
from vigil.runtime import FrameClassifier
from worker.training.cross_validation import cross_validate, select
from worker.training.data import from_urfd
from worker.training.estimators import ModelSpec
from worker.training.publish import publish
from worker.training.specs import PAPER_SVM
from worker.training.splits import grouped_folds
from worker.training.trainers import SklearnTrainer

NAMES = [f"fall-{i:02d}" for i in range(1, 9)] + [
    f"adl-{i:02d}" for i in (1, 5, 10, 11, 30, 31, 33, 34)
]
SMALL_RF = ModelSpec(
    "rf-small",
    "rf",
    {"n_estimators": [20], "max_depth": [6, 10], "min_samples_leaf": [5], "max_features": [0.3]},
)


@pytest.fixture(scope="module")
def data():
    return from_urfd(names=NAMES)


def test_grouped_folds_never_leak_a_sequence():
    positive = np.array([True] * 30 + [False] * 40)
    folds = grouped_folds(positive, 5, seed=7)
    seen = np.concatenate([test for _, test in folds])
    assert sorted(seen.tolist()) == list(range(70))  # every sequence tested exactly once
    for train, test in folds:
        assert not set(train) & set(test)
        assert positive[test].sum() == 6 and (~positive[test]).sum() == 8


def test_cross_validation_frames_of_a_sequence_stay_in_one_fold(data):
    for train, test in grouped_folds(data.is_positive_sequence, 4):
        train_frames, test_frames = data.frames_of(train), data.frames_of(test)
        assert not (train_frames & test_frames).any()
        assert not set(data.group[train_frames]) & set(data.group[test_frames])


def test_small_end_to_end_training_exports_a_working_model(data, tmp_path):
    trainer = SklearnTrainer(SMALL_RF)
    cv = cross_validate(trainer, data, n_folds=4, n_inner=3)
    result = cv.result
    assert result["falls_total"] == 8 and result["adl_total"] == 8
    assert len(result["events"]) == 16
    assert 0 <= result["frame_recall"] <= 1 and result["frame_f1"] > 0.3  # learns something real
    # thresholds and delays were chosen per fold on training sequences only
    assert len(result["fold_operating_points"]) == 4

    selected = select(trainer, data, np.arange(len(data.names)), n_inner=3)
    manifest = publish(trainer, selected, data, tmp_path / "model")
    assert manifest.threshold == selected.threshold
    classifier = load_classifier(tmp_path / "model")

    # the runtime reproduces the evaluation path (features, ONNX scores, threshold, delay)
    runtime = FrameClassifier.from_dir(tmp_path / "model")
    from vigil.datasets import urfd

    seq = urfd.load(names=["fall-03"])[0]
    decisions = [runtime.classify(f).decision for f in seq.frames()]
    features = extract_sequence(seq.frames())
    scores = classifier.predict_proba(features)
    python_scores = selected.fitted.predict_proba(features)
    np.testing.assert_allclose(scores, python_scores, atol=1e-4)
    raw = raw_decisions(scores, manifest.classes, manifest.threshold)
    expected = apply_delay(raw, seq.timestamps, manifest.delay_ms / 1000)
    assert [manifest.classes.index(d) for d in decisions] == expected.tolist()
    assert Decision.EMERGENCY in decisions


def test_paper_svm_configuration_is_fixed():
    (point,) = PAPER_SVM.param_grid(n_features=81)
    pipeline = PAPER_SVM.pipeline(81).set_params(**{k: v for k, (v,) in point.items()})
    model = pipeline.steps[-1][1]
    assert (model.kernel, model.degree, model.C, model.coef0) == ("poly", 2, 0.5, 0.0)
    assert model.gamma == 1 / 81  # gamma = 1/n_features, the very float the paper's SVC had
