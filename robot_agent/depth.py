"""Depth per keypoint from a 16-bit depth image: median over a small window, zeros ignored."""

from __future__ import annotations

import numpy as np

#: URFD fall sequences: distance in millimetres is P * 6000 / 65535 (ADL: 7000 / 65535).
URFD_FALL_MM_PER_UNIT = 6000 / 65535
URFD_ADL_MM_PER_UNIT = 7000 / 65535


def sample_depth(
    depth_image: np.ndarray,
    keypoints: np.ndarray,
    mm_per_unit: float = 1.0,
    window: int = 5,
) -> np.ndarray:
    """Depth in metres (25,) at each keypoint; NaN where the keypoint is missing, outside the
    image, or every reading in its ``window`` x ``window`` neighbourhood is 0 (no reading).

    keypoints must be in the depth image's pixel coordinates.
    """
    if depth_image.ndim != 2:
        raise ValueError(f"depth image must be 2-D, got shape {depth_image.shape}")
    height, width = depth_image.shape
    half = window // 2
    out = np.full(len(keypoints), np.nan, np.float32)
    for i, (x, y, conf) in enumerate(keypoints):
        if conf <= 0 or not (np.isfinite(x) and np.isfinite(y)):
            continue
        col, row = int(round(float(x))), int(round(float(y)))
        if not (0 <= col < width and 0 <= row < height):
            continue
        rows = slice(max(0, row - half), row + half + 1)
        cols = slice(max(0, col - half), col + half + 1)
        patch = depth_image[rows, cols]
        readings = patch[patch > 0]
        if readings.size:
            out[i] = float(np.median(readings)) * mm_per_unit / 1000.0
    return out
