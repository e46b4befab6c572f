"""Depth pictures for the importers: vigil.depth's reader with the labelling domain's error.

Depth at keypoints has one implementation, `vigil.depth.sample_depth` (the robot's sampler):
every importer calls it, so the depth stored with a recording is the depth the robot computes
from the same picture (docs/detection.md, "train equals serve").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from backend.labelling.errors import LabellingError
from vigil import depth


def read_depth_png(path: Path) -> np.ndarray:
    try:
        return depth.read_depth_png(path)
    except ValueError as error:
        raise LabellingError(f"depth: {error}") from error
