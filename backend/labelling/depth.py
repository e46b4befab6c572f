"""Depth per keypoint from 16-bit depth pictures (Kinect / OpenNI PNGs)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from backend.labelling.errors import LabellingError

WINDOW = 2  # median over a (2w+1)^2 window: single pixels at edges are often 0 (no reading)


def read_depth_png(path: Path) -> np.ndarray:
    picture = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if picture is None:
        raise LabellingError(f"depth: {path.name} is not a readable picture")
    if picture.dtype != np.uint16 or picture.ndim != 2:
        raise LabellingError(f"depth: {path.name} must be a 16-bit single-channel PNG")
    return picture


def depth_at_keypoints(
    picture: np.ndarray, keypoints: np.ndarray, metres_per_unit: float, scale: float = 1.0
) -> np.ndarray:
    """(25,) metres for keypoints (25, 3) in pixels (times `scale` to reach the picture);
    NaN where the keypoint is missing or the picture has no reading there."""
    height, width = picture.shape
    depth = np.full(len(keypoints), np.nan, np.float32)
    for i, (x, y, confidence) in enumerate(keypoints):
        if confidence <= 0:
            continue
        px, py = int(round(x * scale)), int(round(y * scale))
        if not (0 <= px < width and 0 <= py < height):
            continue
        window = picture[
            max(py - WINDOW, 0) : py + WINDOW + 1, max(px - WINDOW, 0) : px + WINDOW + 1
        ]
        readings = window[window > 0]
        if readings.size:
            depth[i] = float(np.median(readings)) * metres_per_unit
    return depth
