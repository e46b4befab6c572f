"""MediaPipe source settings without MediaPipe: a stand-in pose module records how the source
builds its estimator and returns landmarks we choose (docs/detection.md, "Across pose
estimators")."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from robot_agent.sources import mediapipe_video
from robot_agent.sources.mediapipe_video import MediaPipeVideoSource
from robot_agent.sources.replay import SourceError
from vigil.skeleton import INDEX


class _Pose:
    built: list[dict] = []

    def __init__(self, **kwargs) -> None:
        _Pose.built.append(kwargs)

    def process(self, image):
        points = []
        for i in range(33):
            visibility = 0.2 if i in (13, 15) else 0.9  # left elbow and wrist barely visible
            points.append(SimpleNamespace(x=0.5, y=0.1 + i / 40, z=0.0, visibility=visibility))
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


def test_landmarks_mediapipe_does_not_see_are_missing_keypoints(video):
    person = next(iter(MediaPipeVideoSource(video))).people[0]
    conf = person.keypoints[:, 2]
    assert conf[INDEX["l_elbow"]] == 0 and conf[INDEX["l_wrist"]] == 0
    assert (person.keypoints[INDEX["l_wrist"], :2] == 0).all()  # no guessed position either
    assert conf[INDEX["r_elbow"]] == pytest.approx(0.9)
    # all of them, as before, when asked for
    everything = next(iter(MediaPipeVideoSource(video, min_visibility=0.0))).people[0]
    assert everything.keypoints[INDEX["l_wrist"], 2] == pytest.approx(0.2)


def test_min_visibility_must_be_a_share(video):
    with pytest.raises(SourceError, match="min_visibility"):
        MediaPipeVideoSource(video, min_visibility=1.5)
