"""Where the agent's frames come from. Every source yields Observation objects."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from vigil.classes import Decision
from vigil.skeleton import SkeletonFrame


@dataclass(slots=True)
class Observation:
    """One camera frame: everybody the pose estimator found, and what else the camera saw."""

    timestamp: float  # seconds from the start of the recording
    people: list[SkeletonFrame]
    depth_image: np.ndarray | None = None  # 16-bit raw depth, same pixel grid as keypoints
    rgb: np.ndarray | None = None  # BGR image, for the ArUco marker
    truth: Decision | None = None  # ground truth (generated data and labelled replays only)
    new_transport: bool = False  # the first frame of a transport
    extra: dict = field(default_factory=dict)


Source = Iterator[Observation]
