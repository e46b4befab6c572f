import numpy as np

from vigil.classes import Decision, TransportMode
from vigil.formats.coco import MOVENET13, movenet13_to_body25
from vigil.runtime import FrameClassifier
from vigil.synthetic import generate_transport
from worker.training.cross_validation import select
from worker.training.estimators import ModelSpec
from worker.training.generated import generated_frames, hard_negatives, patient_arrays
from worker.training.publish import publish
from worker.training.trainers import SklearnTrainer

TINY_MLP = ModelSpec(
    "mlp-tiny",
    "mlp",
    {
        "hidden_layer_sizes": [(32,)],
        "alpha": [1e-3],
        "learning_rate_init": [3e-3],
        "activation": ["relu"],
    },
)


def test_generated_frames_cover_three_classes_and_are_marked_generated():
    data = generated_frames(TransportMode.COMBINED, repeats=1, seed=3)
    assert set(np.unique(data.target)) == {0, 1, 2}
    assert data.generated and all(name.startswith("gen-") for name in data.names)
    assert data.is_positive_sequence.any() and not data.is_positive_sequence.all()


def test_wheelchair_mode_trains_end_to_end_with_three_classes(tmp_path):
    data = generated_frames(TransportMode.WHEELCHAIR, repeats=2, seed=1)
    trainer = SklearnTrainer(TINY_MLP)
    selected = select(trainer, data, np.arange(len(data.names)), n_inner=3, stride=3)
    manifest = publish(trainer, selected, data, tmp_path / "wheelchair")
    assert manifest.generated_data
    assert manifest.classes == [Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE]
    runtime = FrameClassifier.from_dir(tmp_path / "wheelchair")
    transport = generate_transport(
        "wheelchair", seed=99, duration_s=8, events=["slumped_unconscious_wheelchair"]
    )
    keypoints, depth, _, floor = patient_arrays(transport)
    from vigil.skeleton import SkeletonFrame

    out = [
        runtime.classify(SkeletonFrame(k, d, t / transport.fps, f))
        for t, (k, d, f) in enumerate(zip(keypoints, depth, floor, strict=True))
    ]
    assert set(out[0].scores) == {Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE}
    truth = transport.decisions(TransportMode.WHEELCHAIR)
    predicted = [c.decision for c in out]
    emergency = [p for p, g in zip(predicted, truth, strict=True) if g == Decision.EMERGENCY]
    assert emergency.count(Decision.EMERGENCY) > len(emergency) / 2  # the slump is recognised


def test_generated_walking_frames_without_depth_join_real_data_and_say_generated(tmp_path):
    """make run's demo model: URFD plus GENERATED walking transports (worker.training.cli
    training_data). Depth is removed from the generated frames, so `has_depth` cannot tell them
    from URFD's and the model needs keypoints and floor measures only, as a URFD model; the
    concatenation renumbers the sequences, keeps the recordings and is marked generated."""
    from dataclasses import replace

    from vigil.features import FEATURE_NAMES
    from worker.training.data import concatenate

    generated = generated_frames(TransportMode.WALKING, repeats=1, seed=7, depth=False)
    assert np.isnan(
        np.array([f.depth for r in generated.recordings for o in r for f in o.people])
    ).all()
    assert generated.features[:, FEATURE_NAMES.index("has_depth")].max() == 0
    assert generated.features[generated.usable, FEATURE_NAMES.index("has_floor")].min() == 1
    with_depth = generated_frames(TransportMode.WALKING, repeats=1, seed=7)
    assert with_depth.features[with_depth.usable, FEATURE_NAMES.index("has_depth")].mean() > 0.9

    real = replace(generated, generated=False, names=[f"real-{n}" for n in generated.names])
    both = concatenate(real, generated)
    assert both.generated and not real.generated
    assert both.names == real.names + generated.names
    assert np.array_equal(
        both.group, np.concatenate([real.group, generated.group + len(real.names)])
    )
    assert len(both.recordings) == len(both.names) == both.group.max() + 1
    assert both.data_sha256 not in (real.data_sha256, generated.data_sha256)

    spec = ModelSpec(
        "rf-tiny",
        "rf",
        {"n_estimators": [10], "max_depth": [6], "min_samples_leaf": [5], "max_features": [0.3]},
    )
    trainer = SklearnTrainer(spec)
    selected = select(trainer, both, np.arange(len(both.names)), n_inner=3, stride=3)
    manifest = publish(trainer, selected, both, tmp_path / "demo")
    assert manifest.generated_data
    assert list(manifest.inputs) == ["keypoints", "floor"]


def test_hard_negatives_are_normal_generated_transports_shown_as_urfd_shows_people():
    """Only the keypoints URFD's MoveNet gives (and the neck and mid-hip made from them), each
    with confidence 1, no depth: a model cannot tell them from URFD by those."""
    data = hard_negatives(repeats=2)
    assert data.generated and not data.is_positive_sequence.any()
    assert set(np.unique(data.target)) == {0}  # Normal
    urfd_slots = movenet13_to_body25(np.ones((1, len(MOVENET13), 3), np.float32))[0, :, 2] > 0
    for recording in data.recordings:
        for observation in recording:
            for person in observation.people:
                present = person.keypoints[:, 2] > 0
                assert not (present & ~urfd_slots).any()
                assert set(np.unique(person.keypoints[:, 2])) <= {0.0, 1.0}
                assert np.isnan(person.depth).all()
