"""COCO-17 and MoveNet-13 (the URFD csv layout: COCO without eyes and ears) -> SkeletonFrame."""

from __future__ import annotations

import numpy as np

from vigil.formats._body25 import map_to_body25, scale_xy
from vigil.skeleton import SkeletonFrame

COCO17: tuple[str, ...] = (
    "nose",
    "l_eye",
    "r_eye",
    "l_ear",
    "r_ear",
    "l_shoulder",
    "r_shoulder",
    "l_elbow",
    "r_elbow",
    "l_wrist",
    "r_wrist",
    "l_hip",
    "r_hip",
    "l_knee",
    "r_knee",
    "l_ankle",
    "r_ankle",
)
MOVENET13: tuple[str, ...] = (
    "nose",
    "l_shoulder",
    "r_shoulder",
    "l_elbow",
    "r_elbow",
    "l_wrist",
    "r_wrist",
    "l_hip",
    "r_hip",
    "l_knee",
    "r_knee",
    "l_ankle",
    "r_ankle",
)


def _with_confidence(points: np.ndarray, count: int, fmt: str) -> np.ndarray:
    points = np.asarray(points, dtype=np.float32)
    if points.ndim < 2 or points.shape[-2] != count or points.shape[-1] not in (2, 3):
        raise ValueError(f"{fmt}: expected shape (..., {count}, 2 or 3), got {points.shape}")
    if points.shape[-1] == 3:
        return points
    # No scores (URFD csv): the extractor wrote 0,0 for keypoints below its threshold.
    present = ~np.all(points == 0, axis=-1, keepdims=True)
    return np.concatenate([points, present.astype(np.float32)], axis=-1)


def coco17_to_body25(points: np.ndarray, image_size: tuple[float, float] | None = None):
    """(n, 17, 2|3) -> (n, 25, 3)."""
    return map_to_body25(scale_xy(_with_confidence(points, 17, "coco17"), image_size), COCO17)


def movenet13_to_body25(points: np.ndarray, image_size: tuple[float, float] | None = None):
    """(n, 13, 2|3) -> (n, 25, 3). Without a score column, (0, 0) means missing."""
    return map_to_body25(scale_xy(_with_confidence(points, 13, "movenet13"), image_size), MOVENET13)


def from_coco17(
    points: np.ndarray, timestamp: float = 0.0, image_size: tuple[float, float] | None = None
) -> SkeletonFrame:
    """(17, 3) x, y, score in COCO order -> SkeletonFrame."""
    return SkeletonFrame(
        coco17_to_body25(np.asarray(points)[None], image_size)[0], timestamp=timestamp
    )


def from_movenet13(
    points: np.ndarray, timestamp: float = 0.0, image_size: tuple[float, float] | None = None
) -> SkeletonFrame:
    """(13, 2) as in the URFD csv (x, y; 0,0 = missing) or (13, 3) with scores -> SkeletonFrame."""
    return SkeletonFrame(
        movenet13_to_body25(np.asarray(points)[None], image_size)[0], timestamp=timestamp
    )
