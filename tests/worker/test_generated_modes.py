import numpy as np

from vigil.classes import Decision, TransportMode
from vigil.runtime import FrameClassifier
from vigil.skeleton import SkeletonFrame
from vigil.synthetic_transports import class_targets, generate_transports
from worker.training.cross_validation import select
from worker.training.estimators import ModelSpec
from worker.training.generated import generated_frames
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


def test_generator_covers_every_class_and_drops_keypoints():
    sequences = generate_transports(TransportMode.COMBINED, repeats=1, seed=3)
    targets = np.concatenate([class_targets(s, TransportMode.COMBINED) for s in sequences])
    assert set(np.unique(targets)) == {0, 1, 2}
    keypoints = np.concatenate([s.keypoints for s in sequences])
    assert (keypoints[:, :, 2] == 0).mean() > 0.01
    assert all(s.generated and s.name.startswith("gen-") for s in sequences)
    depth = np.concatenate([s.depth for s in sequences])
    assert np.isnan(depth).any() and np.nanmax(depth) > 3.5  # too far away


def test_wheelchair_mode_trains_end_to_end_with_three_classes(tmp_path):
    data = generated_frames(TransportMode.WHEELCHAIR, repeats=3, seed=1)
    trainer = SklearnTrainer(TINY_MLP)
    selected = select(trainer, data, np.arange(len(data.names)), n_inner=3, stride=2)
    manifest = publish(trainer, selected, data, tmp_path / "wheelchair")
    assert manifest.generated_data and manifest.classes == [
        Decision.NORMAL,
        Decision.EMERGENCY,
        Decision.PAUSE,
    ]
    runtime = FrameClassifier.from_dir(tmp_path / "wheelchair")
    seq = next(s for s in generate_transports("wheelchair", 1, seed=9) if "slump" in s.name)
    out = [
        runtime.classify(SkeletonFrame(k, d, float(t)))
        for k, d, t in zip(seq.keypoints, seq.depth, seq.timestamps, strict=True)
    ]
    assert set(out[0].scores) == {Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE}
    assert out[-1].decision == Decision.EMERGENCY  # slumped for seconds at the end
