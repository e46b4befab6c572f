"""MediaPipe source settings without MediaPipe: a stand-in pose module records how the source
builds its estimator and returns landmarks we choose (docs/detection.md, "Across pose
estimators")."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from robot_agent.sources import mediapipe_video
from robot_agent.sources.mediapipe_video import MediaPipeVideoSource


class _Pose:
    built: list[dict] = []

    def __init__(self, **kwargs) -> None:
        _Pose.built.append(kwargs)

    def process(self, image):
        points = []
        for i in range(33):
            points.append(SimpleNamespace(x=0.5, y=0.1 + i / 40, z=0.0, visibility=0.9))
        return SimpleNamespace(pose_landmarks=SimpleNamespace(landmark=points))

    def close(self) -> None:
        pass


@pytest.fixture
def video(tmp_path, monkeypatch):
    monkeypatch.setattr(mediapipe_video, "load_mediapipe_pose", lambda: SimpleNamespace(Pose=_Pose))
    _Pose.built.clear()
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (64, 48))
    for _ in range(3):
        writer.write(np.full((48, 64, 3), 128, np.uint8))
    writer.release()
    return path


def test_follows_the_person_it_found_down_to_a_low_landmark_presence(video):
    observations = list(MediaPipeVideoSource(video))
    assert len(observations) == 3
    (built,) = _Pose.built
    assert built["static_image_mode"] is False  # tracking, not a detection in every frame
    assert built["min_tracking_confidence"] == mediapipe_video.MIN_TRACKING_CONFIDENCE == 0.1
    assert built["min_detection_confidence"] == 0.3
