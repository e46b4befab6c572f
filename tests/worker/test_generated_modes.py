import numpy as np

from vigil.classes import Decision, TransportMode
from vigil.runtime import FrameClassifier
from vigil.synthetic import generate_transport
from worker.training.cross_validation import select
from worker.training.estimators import ModelSpec
from worker.training.generated import generated_frames, patient_arrays
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
