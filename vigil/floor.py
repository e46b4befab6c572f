"""Floor measures of a person from depth at the keypoints and the camera's mounting.

A pinhole camera (focal lengths and principal point in the keypoints' units) mounted at
`height_m` above the floor and pitched down by `pitch_deg` turns each keypoint with a depth into
a height above the floor. The floor measures (vigil.skeleton.FLOOR_FIELDS) are the highest
keypoint, the mean height and the share of keypoints within FLOOR_NEAR_M of the floor: the same
quantities URFD's depth features give for the whole silhouette (H, D, P40), which is what lets a
model trained on URFD use them. Keypoints are sparser than a silhouette: a keypoint-based top
lies a little below the head's top (eyes, ears), a difference stated wherever results are shown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vigil.skeleton import FLOOR_NEAR_M

MIN_KEYPOINTS_WITH_DEPTH = 4


@dataclass(frozen=True, slots=True)
class CameraMount:
    fx: float
    fy: float
    cx: float
    cy: float
    height_m: float  # optical centre above the floor
    pitch_deg: float = 0.0  # downwards tilt of the optical axis

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "height_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"camera mount {name} must be a positive number, got {value!r}")
        if not -90.0 < self.pitch_deg < 90.0:
            raise ValueError(f"camera mount pitch_deg must lie in (-90, 90), got {self.pitch_deg}")

    def heights(self, keypoints: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Height above the floor (m) of each keypoint (..., 25, 3) with depth (..., 25) as the
        distance along the optical axis; NaN where the keypoint is missing or has no depth."""
        keypoints = np.asarray(keypoints, np.float64)
        z = np.asarray(depth, np.float64)
        y_down = (keypoints[..., 1] - self.cy) * z / self.fy
        pitch = math.radians(self.pitch_deg)
        height = self.height_m - (y_down * math.cos(pitch) + z * math.sin(pitch))
        known = (keypoints[..., 2] > 0) & np.isfinite(z) & (z > 0)
        return np.where(known, height, np.nan)


def floor_measures(keypoints: np.ndarray, depth: np.ndarray, mount: CameraMount) -> np.ndarray:
    """(25, 3) keypoints and (25,) depth -> (3,) floor measures, NaN if too few keypoints have
    depth to say anything."""
    return floor_measures_many(np.asarray(keypoints)[None], np.asarray(depth)[None], mount)[0]


def floor_measures_many(keypoints: np.ndarray, depth: np.ndarray, mount: CameraMount) -> np.ndarray:
    """(n, 25, 3) keypoints and (n, 25) depth -> (n, 3) floor measures, vectorised."""
    heights = mount.heights(keypoints, depth)
    known = np.isfinite(heights)
    count = known.sum(axis=1)
    safe = np.where(known, heights, 0.0)
    top = np.where(known, heights, -np.inf).max(axis=1)
    centre = safe.sum(axis=1) / np.maximum(count, 1)
    near = (known & (safe < FLOOR_NEAR_M)).sum(axis=1) / np.maximum(count, 1)
    floor = np.stack([top, centre, near], axis=1)
    floor[count < MIN_KEYPOINTS_WITH_DEPTH] = np.nan
    return floor.astype(np.float32)
