"""What every keypoint source yields: one Observation per camera frame.

The agent's pipeline is source -> patient tracking -> depth sampling -> classification ->
outbox; sources know nothing of the later steps.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from vigil.skeleton import SkeletonFrame


@dataclass(slots=True)
class Observation:
    """Everybody the pose estimator found in one camera frame.

    people: BODY_25 skeletons in pixels (depth NaN until sampled, unless the source knows it).
    rgb: the colour image (H, W, 3) uint8 BGR when the source has one (ArUco patient marker).
    depth_image: raw 16-bit depth image when the source has one; depth_scale_mm converts a raw
    value to millimetres (URFD fall sequences: 6000 / 65535).
    truth: ground-truth fine label of the patient when the source is generated or labelled.
    """

    timestamp: float
    people: list[SkeletonFrame]
    index: int = 0
    rgb: np.ndarray | None = None
    depth_image: np.ndarray | None = None
    depth_scale_mm: float = 1.0
    truth: str | None = None
    patient_hint: int | None = field(default=None)  # generated scenes know who the patient is


class KeypointSource(Protocol):
    """An iterable of observations; `realtime` sources pace themselves at their frame rate."""

    name: str
    fps: float

    def __iter__(self) -> Iterator[Observation]: ...
