"""One camera frame as the pose estimator saw it: everybody found in it, and what else the
source knows (colour image, depth image, ground truth of generated or labelled recordings).

The frame path is observation -> patient tracking (vigil.tracking) -> depth at the keypoints
(vigil.depth) -> floor measures (vigil.floor) -> features -> model -> policy (vigil.detector);
robots, benchmarks and evaluations all run it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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
