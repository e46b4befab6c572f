"""The GENERATED scene generator: coverage of the taxonomy, determinism, camera realism."""

import numpy as np
import pytest

from vigil.classes import Decision, TransportMode
from vigil.synthetic import (
    EVENTS_BY_LOCOMOTION,
    FPS,
    IMAGE_HEIGHT,
    IMAGE_WIDTH,
    LABELS_BY_LOCOMOTION,
    Locomotion,
    class_targets,
    generate_transport,
)
from vigil.taxonomy import DEFAULT_TAXONOMY


@pytest.fixture(scope="module")
def full_transports():
    return {
        loc: generate_transport(loc, seed=11, events=EVENTS_BY_LOCOMOTION[loc], n_people=2)
        for loc in Locomotion
    }


@pytest.mark.parametrize("locomotion", list(Locomotion))
def test_every_event_covers_every_label_of_its_mode(full_transports, locomotion):
    transport = full_transports[locomotion]
    assert set(transport.labels) == LABELS_BY_LOCOMOTION[locomotion]
    assert transport.generated
    assert transport.fps == FPS == 30.0
    decisions = set(transport.decisions())
    expected = {Decision.NORMAL, Decision.EMERGENCY}
    if locomotion is Locomotion.WHEELCHAIR:
        expected.add(Decision.PAUSE)
    assert decisions == expected
    # combined mode: every class (Pause situations become Pause there, not Normal)
    combined = set(transport.decisions(TransportMode.COMBINED))
    assert Decision.PAUSE in combined


def test_modes_together_cover_the_whole_taxonomy():
    union = set().union(*LABELS_BY_LOCOMOTION.values())
    assert union == {label.key for label in DEFAULT_TAXONOMY.labels}


def test_same_seed_same_transport_other_seed_differs():
    a = generate_transport("rollator", seed=3, duration_s=8, n_people=3)
    b = generate_transport("rollator", seed=3, duration_s=8, n_people=3)
    c = generate_transport("rollator", seed=4, duration_s=8, n_people=3)
    assert a.labels == b.labels and a.patient_index == b.patient_index
    for pa, pb in zip(a.frames_per_person, b.frames_per_person, strict=True):
        for fa, fb in zip(pa, pb, strict=True):
            assert (fa is None) == (fb is None)
            if fa is not None:
                np.testing.assert_array_equal(fa.keypoints, fb.keypoints)
    pa = a.patient_sequence().keypoints
    pc = c.patient_sequence().keypoints
    assert pa.shape != pc.shape or not np.array_equal(pa, pc)


def test_camera_realism_pixels_depth_and_dropped_keypoints(full_transports):
    transport = full_transports[Locomotion.WALKING]
    seq = transport.patient_sequence()
    present = seq.keypoints[:, :, 2] > 0
    xy = seq.keypoints[present][:, :2]
    assert (xy[:, 0] >= 0).all() and (xy[:, 0] < IMAGE_WIDTH).all()
    assert (xy[:, 1] >= 0).all() and (xy[:, 1] < IMAGE_HEIGHT).all()
    seen = present.sum(1) > 0
    assert 0.01 < 1 - present[seen].mean() < 0.3  # some keypoints dropped, most kept
    depth = seq.depth[present]
    assert 1.0 < np.nanmedian(depth) < 4.0  # metres, following distance
    assert np.nanmax(depth) > 4.5  # the too_far_away event
    assert np.isnan(seq.depth[seen]).any()
    far = np.array([k == "too_far_away" for k in transport.labels]) & seen
    near = np.array([k == "walking" for k in transport.labels]) & seen
    assert np.nanmedian(seq.depth[far]) > np.nanmedian(seq.depth[near]) + 1.0
    targets = class_targets(seq, TransportMode.WALKING)
    assert set(np.unique(targets)) == {0, 1}


def test_bystanders_are_people_in_view_and_detections_are_shuffled():
    transport = generate_transport("walking", seed=5, duration_s=10, n_people=5)
    assert transport.n_people == 5
    counts = [sum(f is not None for f in person) for person in transport.frames_per_person]
    assert all(c > 0 for c in counts)  # every bystander crosses the view at some point
    assert counts[transport.patient_index] > 0.9 * transport.n_frames
    crowded = next(t for t in range(transport.n_frames) if len(transport.detection_ids(t)) >= 2)
    ids = transport.detection_ids(crowded)
    frames = transport.detections(crowded)
    for person, frame in zip(ids, frames, strict=True):
        assert frame is transport.frames_per_person[person][crowded]
    with pytest.raises(ValueError, match="n_people"):
        generate_transport("walking", n_people=6)
    with pytest.raises(ValueError, match="not possible when wheelchair"):
        generate_transport("wheelchair", events=["kneeling"])


def test_lying_down_deliberately_is_on_a_bed_not_on_the_floor():
    """A look-alike must not be the real thing: lying down deliberately (a bed, a couch) puts the
    body clearly above the floor, unlike the end of a fall (the floor measures say so: mean
    keypoint height and share of keypoints near the floor). It once used a 0.15 m "bed", floor
    level, and the demo's model rightly alarmed on it."""
    lying, fallen = [], []
    for seed in range(6):
        transport = generate_transport(
            "walking",
            seed=seed,
            duration_s=20,
            events=["lying_down_deliberately", "fall"],
            n_people=1,
        )
        floor = transport.patient_sequence().floor
        labels = np.array(transport.labels)
        lying.append(np.nanmedian(floor[labels == "lying_down_deliberately"][-15:], axis=0))
        fallen.append(np.nanmedian(floor[labels == "lying_on_floor"], axis=0))
    lying, fallen = np.array(lying), np.array(fallen)
    assert (lying[:, 1] > 0.45).all(), lying  # mean height above the floor, metres
    assert (lying[:, 2] < 0.3).all(), lying  # share of keypoints near the floor
    assert (fallen[:, 1] < 0.3).all() and (fallen[:, 2] > 0.5).all(), fallen
