"""GENERATED hard negatives beside real recordings: in every training fold, never evaluated."""

from __future__ import annotations

import numpy as np
import pytest

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from worker.training.cross_validation import cross_validate
from worker.training.data import from_urfd, with_training_only
from worker.training.estimators import ModelSpec
from worker.training.generated import BED_EVENT, bed_frames, bed_recordings
from worker.training.splits import grouped_folds
from worker.training.trainers import SklearnTrainer

NAMES = ["fall-01", "fall-02", "fall-03", "adl-01", "adl-02", "adl-10"]


@pytest.fixture(scope="module")
def data():
    return with_training_only(from_urfd(names=NAMES), bed_frames(3))


def test_bed_transports_lie_down_on_a_bed_and_are_normal_generated_frames():
    recordings, digest = bed_recordings(3)
    normal = MODE_CLASSES[TransportMode.WALKING].index(Decision.NORMAL)
    assert len(recordings) == 3 and len({r.name for r in recordings}) == 3
    for recording in recordings:
        assert BED_EVENT in recording.name and recording.generated
        assert np.all(recording.target == normal)  # lying on a bed is not an emergency
        seen = [o for o in recording.observations if o.people]
        assert seen and all(np.isnan(o.people[0].depth).all() for o in seen)  # as URFD: no depth
    assert bed_recordings(3)[1] == digest and bed_recordings(3, seed=1)[1] != digest


def test_training_only_sequences_train_every_fold_and_are_never_evaluated(data):
    evaluated = np.arange(len(NAMES))
    assert np.array_equal(data.evaluated, evaluated) and data.generated
    assert data.names[len(NAMES) :] == [n for n in data.names if n.startswith("gen-")]
    spec = ModelSpec(
        "rf-tiny", "rf", {"n_estimators": [5], "max_depth": [3]}, feature_set="keypoints"
    )
    cv = cross_validate(SklearnTrainer(spec), data, n_folds=3, n_inner=2, stride=6)
    generated = set(range(len(NAMES), len(data.names)))
    urfd_alone = grouped_folds(data.is_positive_sequence[: len(NAMES)], 3, 0)
    for fold, held_out, (_, test) in zip(cv.folds, cv.test_scores, urfd_alone, strict=True):
        assert np.array_equal(held_out.sequences, np.sort(test))  # the folds URFD has alone
        assert not set(held_out.sequences) & generated
        assert generated <= set(fold.oof.sequences)  # trained on in every fold
    assert cv.result["adl_total"] == 3 and cv.result["falls_total"] == 3
