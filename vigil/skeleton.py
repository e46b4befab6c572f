"""The canonical skeleton: OpenPose BODY_25 keypoints (x, y, confidence) plus depth per keypoint,
and, where the depth camera's pose over the floor is known, the body's height above the floor."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

BODY_25: tuple[str, ...] = (
    "nose",
    "neck",
    "r_shoulder",
    "r_elbow",
    "r_wrist",
    "l_shoulder",
    "l_elbow",
    "l_wrist",
    "mid_hip",
    "r_hip",
    "r_knee",
    "r_ankle",
    "l_hip",
    "l_knee",
    "l_ankle",
    "r_eye",
    "l_eye",
    "r_ear",
    "l_ear",
    "l_big_toe",
    "l_small_toe",
    "l_heel",
    "r_big_toe",
    "r_small_toe",
    "r_heel",
)
N_KEYPOINTS = len(BODY_25)
INDEX = {name: i for i, name in enumerate(BODY_25)}

#: Floor measures of a person, from depth and the camera's mounting over the floor (vigil.floor):
#: height of the body's top above the floor, height of its centre, and the share of the body
#: within FLOOR_NEAR_M of the floor. NaN where unknown (no depth, or the camera pose unknown).
FLOOR_FIELDS: tuple[str, ...] = ("top_height_m", "centre_height_m", "near_floor_share")
N_FLOOR = len(FLOOR_FIELDS)
FLOOR_NEAR_M = 0.4


def no_floor() -> np.ndarray:
    return np.full(N_FLOOR, np.nan, np.float32)


#: Bones for drawing: pairs of keypoint indices.
BONES: tuple[tuple[int, int], ...] = (
    (1, 0),
    (0, 15),
    (15, 17),
    (0, 16),
    (16, 18),
    (1, 2),
    (2, 3),
    (3, 4),
    (1, 5),
    (5, 6),
    (6, 7),
    (1, 8),
    (8, 9),
    (9, 10),
    (10, 11),
    (11, 24),
    (11, 22),
    (22, 23),
    (8, 12),
    (12, 13),
    (13, 14),
    (14, 21),
    (14, 19),
    (19, 20),
)


@dataclass(slots=True)
class SkeletonFrame:
    """One person in one frame.

    keypoints: (25, 3) float32, x and y in image units (pixels or normalised), confidence 0..1;
    a missing keypoint has confidence 0 (its x, y are meaningless, never real zeros).
    depth: (25,) float32 metres, NaN where unknown.
    floor: (3,) float32 floor measures (FLOOR_FIELDS), NaN where unknown.
    """

    keypoints: np.ndarray
    depth: np.ndarray = field(default_factory=lambda: np.full(N_KEYPOINTS, np.nan, np.float32))
    timestamp: float = 0.0
    floor: np.ndarray = field(default_factory=no_floor)

    def __post_init__(self) -> None:
        self.keypoints = np.asarray(self.keypoints, dtype=np.float32)
        self.depth = np.asarray(self.depth, dtype=np.float32)
        if self.keypoints.shape != (N_KEYPOINTS, 3):
            raise ValueError(f"keypoints must have shape (25, 3), got {self.keypoints.shape}")
        if self.depth.shape != (N_KEYPOINTS,):
            raise ValueError(f"depth must have shape (25,), got {self.depth.shape}")
        self.floor = np.asarray(self.floor, dtype=np.float32)
        if self.floor.shape != (N_FLOOR,):
            raise ValueError(f"floor must have shape ({N_FLOOR},), got {self.floor.shape}")

    @property
    def present(self) -> np.ndarray:
        return self.keypoints[:, 2] > 0


def empty_keypoints() -> np.ndarray:
    return np.zeros((N_KEYPOINTS, 3), np.float32)


def encode_keypoints(keypoints: np.ndarray) -> bytes:
    """Compact storage: 25 x 3 little-endian float32 (300 bytes)."""
    return np.ascontiguousarray(keypoints, dtype="<f4").tobytes()


def decode_keypoints(blob: bytes) -> np.ndarray:
    return np.frombuffer(blob, dtype="<f4").reshape(N_KEYPOINTS, 3).copy()


def encode_depth(depth: np.ndarray) -> bytes:
    """Compact storage: 25 little-endian float32 metres, NaN for unknown (100 bytes)."""
    return np.ascontiguousarray(depth, dtype="<f4").tobytes()


def decode_depth(blob: bytes) -> np.ndarray:
    return np.frombuffer(blob, dtype="<f4").copy()


def depth_to_json(blob: bytes | None) -> list[float | None] | None:
    """A stored depth blob as JSON values: metres, null where unknown (JSON has no NaN)."""
    return None if blob is None else _json_values(decode_depth(blob))


def _json_values(values: np.ndarray) -> list[float | None]:
    return [None if np.isnan(v) else float(v) for v in values]


def encode_floor(floor: np.ndarray) -> bytes | None:
    """Compact storage: 3 little-endian float32 (12 bytes); None when nothing is known."""
    floor = np.asarray(floor, dtype="<f4")
    return None if np.isnan(floor).all() else np.ascontiguousarray(floor).tobytes()


def decode_floor(blob: bytes | None) -> np.ndarray:
    return no_floor() if blob is None else np.frombuffer(blob, dtype="<f4").copy()


def decode_many(blobs: Sequence[bytes | None], width: int) -> np.ndarray:
    """(n, width) float32 from blobs of `width` little-endian float32 each (keypoints: 75,
    depth: 25, floor: 3), a NaN row for None: one decode for a whole recording, the same
    values as decoding each blob."""
    out = np.full((len(blobs), width), np.nan, np.float32)
    present = [i for i, blob in enumerate(blobs) if blob is not None]
    if present:
        size = width * 4
        if any(len(blobs[i]) != size for i in present):
            raise ValueError(f"a stored blob is not {width} float32 values")
        values = np.frombuffer(b"".join(blobs[i] for i in present), dtype="<f4")
        out[present] = values.reshape(len(present), width)
    return out


def floor_to_json(blob: bytes | None) -> list[float | None] | None:
    return None if blob is None else _json_values(decode_floor(blob))
