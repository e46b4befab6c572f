"""The GENERATED transport generator: determinism, label coverage, geometry."""

import numpy as np
import pytest

from vigil.classes import Decision
from vigil.synthetic import EVENTS_BY_LOCOMOTION, Locomotion, generate_transport
from vigil.taxonomy import DEFAULT_TAXONOMY


def test_same_seed_same_transport_and_other_seed_differs():
    a = generate_transport("walking", seed=7, duration_s=6, n_people=2)
    b = generate_transport("walking", seed=7, duration_s=6, n_people=2)
    c = generate_transport("walking", seed=8, duration_s=6, n_people=2)
    assert a.labels == b.labels and a.generated
    ka = np.stack([f.keypoints for f in a.patient_frames if f is not None])
    kb = np.stack([f.keypoints for f in b.patient_frames if f is not None])
    np.testing.assert_array_equal(ka, kb)
    assert (
        a.labels != c.labels
        or a.n_frames != c.n_frames
        or not np.array_equal(
            ka[:10], np.stack([f.keypoints for f in c.patient_frames if f is not None])[:10]
        )
    )


def test_every_fine_label_of_the_taxonomy_can_be_generated():
    seen = set()
    for loc in Locomotion:
        for event in EVENTS_BY_LOCOMOTION[loc]:
            seen |= set(generate_transport(loc, seed=1, duration_s=5, events=[event]).labels)
    assert seen == {label.key for label in DEFAULT_TAXONOMY.labels}


def test_fall_is_emergency_and_geometry_is_in_the_image():
    tr = generate_transport("walking", seed=2, duration_s=12, events=["fall"], n_people=1)
    decisions = tr.decisions()
    assert Decision.EMERGENCY in decisions and Decision.NORMAL in decisions
    assert tr.fps == 30 and len(decisions) == tr.n_frames >= 12 * 30
    frames = [f for f in tr.patient_frames if f is not None]
    assert len(frames) > 0.9 * tr.n_frames
    kp = np.stack([f.keypoints for f in frames])
    present = kp[..., 2] > 0
    assert 0.7 < present.mean() < 1.0  # some keypoints are dropped
    assert kp[..., 0][present].min() >= 0 and kp[..., 0][present].max() < 640
    assert kp[..., 1][present].min() >= 0 and kp[..., 1][present].max() < 480
    depth = np.stack([f.depth for f in frames])
    assert np.isnan(depth[~present]).all()
    assert 1.5 < np.nanmedian(depth) < 4.0  # metres
    # lying on the floor: the hip is much lower in the image than while walking
    hip_y = {lab: [] for lab in ("walking", "lying_on_floor")}
    for f, lab in zip(tr.patient_frames, tr.labels, strict=True):
        if f is not None and lab in hip_y and f.keypoints[8, 2] > 0:
            hip_y[lab].append(f.keypoints[8, 1])
    assert np.median(hip_y["lying_on_floor"]) > np.median(hip_y["walking"]) + 40


def test_bystanders_and_detections_without_identity():
    tr = generate_transport("rollator", seed=4, duration_s=8, n_people=5)
    assert tr.n_people == 5 and 0 <= tr.patient_index < 5
    counts = [len(tr.detections(t)) for t in range(tr.n_frames)]
    assert max(counts) >= 2 and min(counts) >= 0


def test_bad_arguments_name_the_problem():
    with pytest.raises(ValueError, match="n_people"):
        generate_transport("walking", n_people=6)
    with pytest.raises(ValueError, match="slumped"):
        generate_transport("walking", events=["slumped_unconscious_wheelchair"])
    with pytest.raises(ValueError):
        generate_transport("bicycle")
