"""The robot's frame path and the training data agree, on REAL URFD recordings: a model scored
on bulk features and the same model replayed frame by frame through tracker, floor measures,
streaming features, ONNX Runtime and the delay filter decide the same on every frame."""

from __future__ import annotations

import numpy as np
import pytest

from vigil.classes import Decision
from vigil.model_file import load_classifier
from vigil.policy import apply_delay, raw_decisions
from vigil.runtime import FrameClassifier
from worker.evaluation import evaluate_model
from worker.training.cross_validation import select
from worker.training.data import from_urfd
from worker.training.estimators import ModelSpec
from worker.training.publish import publish
from worker.training.robot_path import replay_stream
from worker.training.trainers import SklearnTrainer

# Falls whose first frames are partial detections, a fast fall, and daily activities that
# lose the person: the cases the tracker used to drop.
NAMES = ["fall-01", "fall-24", "fall-26", "adl-13", "adl-30", "adl-01"]


@pytest.fixture(scope="module")
def data():
    return from_urfd(None, NAMES)


@pytest.fixture(scope="module")
def model_dir(data, tmp_path_factory):
    spec = ModelSpec(
        "rf-path",
        "rf",
        {"n_estimators": [20], "max_depth": [8], "min_samples_leaf": [3], "max_features": [0.3]},
    )
    trainer = SklearnTrainer(spec)
    selected = select(trainer, data, np.arange(len(NAMES)), n_inner=2, stride=2)
    out = tmp_path_factory.mktemp("model") / "rf-path"
    publish(trainer, selected, data, out, version="rf-path-1")
    return out


def test_training_frames_are_the_patient_frames_of_every_frame_with_a_person(data):
    detected = np.concatenate([[bool(o.people) for o in rec] for rec in data.recordings])
    assert np.array_equal(data.usable, detected)


def test_bulk_and_robot_path_decide_the_same_on_every_frame(data, model_dir):
    classifier = load_classifier(model_dir)
    manifest = classifier.manifest
    assert manifest.inputs == ["keypoints", "floor"]  # full feature set, URFD's floor measures
    robot, dropped, _ = replay_stream(FrameClassifier(classifier), data)
    assert dropped == 0
    columns = np.arange(data.features.shape[1])
    bulk_scores = classifier.predict_proba(data.features[:, columns])
    normal = manifest.classes.index(Decision.NORMAL)
    for s, times, _, robot_scores in robot.per_sequence():
        rows = data.group == s
        bulk = apply_delay(
            raw_decisions(bulk_scores[rows], manifest.classes, manifest.threshold),
            times,
            manifest.delay_ms / 1000,
            normal,
        )
        assert np.array_equal(bulk, robot.decisions_of(s)), data.names[s]
        np.testing.assert_allclose(robot_scores, bulk_scores[rows], atol=1e-6)
    emergency = manifest.classes.index(Decision.EMERGENCY)
    assert (robot.decisions == emergency).any() and (robot.decisions == normal).any()


def test_gold_set_evaluation_replays_at_the_operating_point_asked_for(data, model_dir):
    classifier = load_classifier(model_dir)
    at_model = evaluate_model(classifier, data)
    no_delay = evaluate_model(classifier, data, delay_ms=0)
    assert at_model["delay_ms"] == classifier.manifest.delay_ms and no_delay["delay_ms"] == 0
    assert at_model["inputs"] == ["keypoints", "floor"]
    # Without the delay filter, at least as many frames turn into an alarm.
    alarms = lambda result: sum(ev["alarms"] for ev in result["events"])  # noqa: E731
    assert alarms(no_delay) >= alarms(at_model)
