"""MediaPipe Pose (33 landmarks: x, y, z, visibility) -> SkeletonFrame (visibility = confidence)."""

from __future__ import annotations

import numpy as np

from vigil.formats._body25 import map_to_body25, scale_xy
from vigil.skeleton import SkeletonFrame

MEDIAPIPE33: tuple[str | None, ...] = (
    "nose",
    None,
    "l_eye",
    None,
    None,
    "r_eye",
    None,
    "l_ear",
    "r_ear",
    None,
    None,
    "l_shoulder",
    "r_shoulder",
    "l_elbow",
    "r_elbow",
    "l_wrist",
    "r_wrist",
    None,
    None,
    None,
    None,
    None,
    None,
    "l_hip",
    "r_hip",
    "l_knee",
    "r_knee",
    "l_ankle",
    "r_ankle",
    "l_heel",
    "r_heel",
    "l_big_toe",
    "r_big_toe",
)


def mediapipe33_to_body25(
    landmarks: np.ndarray, image_size: tuple[float, float] | None = None
) -> np.ndarray:
    """(n, 33, 4) x, y, z, visibility -> (n, 25, 3). z is relative, not metres: it is dropped."""
    landmarks = np.asarray(landmarks, dtype=np.float32)
    if landmarks.ndim != 3 or landmarks.shape[1:] != (33, 4):
        raise ValueError(f"mediapipe33: expected shape (n, 33, 4), got {landmarks.shape}")
    xyc = landmarks[..., [0, 1, 3]]
    return map_to_body25(scale_xy(xyc, image_size), MEDIAPIPE33)


def from_mediapipe33(
    landmarks: np.ndarray, timestamp: float = 0.0, image_size: tuple[float, float] | None = None
) -> SkeletonFrame:
    return SkeletonFrame(
        mediapipe33_to_body25(np.asarray(landmarks)[None], image_size)[0], timestamp=timestamp
    )
