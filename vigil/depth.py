"""Depth at each keypoint from a raw 16-bit depth image.

For every keypoint the raw values in a small square window around it are gathered, zeros (no
reading) are ignored and the median of the rest is converted to metres. A keypoint that is
missing (confidence 0), lies outside the image or has no reading in its window gets NaN.
Vectorised: one gather, one sort, no Python loop over keypoints (a few microseconds per person).

The one implementation of depth at keypoints: the robot (vigil.detector), the importers
(backend.labelling.importers), the training rows and the benchmarks all sample with
`sample_depth`, and read 16-bit depth pictures with `read_depth_png` (docs/detection.md, "train
equals serve").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vigil.observation import Observation
from vigil.skeleton import SkeletonFrame

DEFAULT_WINDOW = 5  # pixels on a side; odd


def read_depth_png(path: Path | str) -> np.ndarray:
    """A 16-bit single-channel depth picture (Kinect / OpenNI PNG) as raw integers; ValueError
    (naming the file) when it is not readable or not 16-bit single-channel."""
    import cv2

    path = Path(path)
    picture = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if picture is None:
        raise ValueError(f"{path.name}: not a readable picture")
    if picture.dtype != np.uint16 or picture.ndim != 2:
        raise ValueError(
            f"{path.name}: depth must be a 16-bit single-channel PNG, got {picture.dtype} "
            f"{picture.shape}"
        )
    return picture


def _offsets(window: int) -> tuple[np.ndarray, np.ndarray]:
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd number of pixels, got {window}")
    half = window // 2
    grid = np.arange(-half, half + 1)
    dy, dx = np.meshgrid(grid, grid, indexing="ij")
    return dy.ravel(), dx.ravel()


def sample_depth(
    depth_image: np.ndarray,
    keypoints: np.ndarray,
    scale_mm: float = 1.0,
    window: int = DEFAULT_WINDOW,
    keypoint_image_size: tuple[float, float] | None = None,
) -> np.ndarray:
    """Depth in metres (..., 25) at keypoints (..., 25, 3) given in pixels.

    depth_image: (H, W) raw integer depth, 0 meaning no reading; raw * scale_mm is millimetres.
    keypoint_image_size: (width, height) of the image the keypoints refer to, when it differs
    from the depth image (e.g. pose found on a smaller RGB frame); None means the same size.
    """
    image = np.asarray(depth_image)
    if image.ndim != 2 or not np.issubdtype(image.dtype, np.integer):
        raise ValueError(
            f"depth image must be a 2-D integer array, got {image.dtype} {image.shape}"
        )
    points = np.asarray(keypoints, dtype=np.float32)
    if points.shape[-1] != 3:
        raise ValueError(f"keypoints must end in (x, y, confidence), got shape {points.shape}")
    height, width = image.shape
    xy = points[..., :2]
    if keypoint_image_size is not None:
        xy = xy * np.array(
            [width / keypoint_image_size[0], height / keypoint_image_size[1]], np.float32
        )
    flat_xy = xy.reshape(-1, 2)
    present = points.reshape(-1, 3)[:, 2] > 0
    col = np.floor(flat_xy[:, 0]).astype(np.int64)
    row = np.floor(flat_xy[:, 1]).astype(np.int64)
    inside = present & (col >= 0) & (col < width) & (row >= 0) & (row < height)
    dy, dx = _offsets(window)
    rows = np.clip(row[:, None] + dy, 0, height - 1)
    cols = np.clip(col[:, None] + dx, 0, width - 1)
    patches = np.sort(image[rows, cols], axis=1)  # zeros (no reading) sort first
    readings = np.count_nonzero(patches, axis=1)
    first = patches.shape[1] - readings
    last = patches.shape[1] - 1
    lo = np.minimum(first + (readings - 1) // 2, last)
    hi = np.minimum(first + readings // 2, last)
    picked = np.arange(len(patches))
    median = (patches[picked, lo].astype(np.float64) + patches[picked, hi]) / 2.0
    metres = median * (scale_mm / 1000.0)
    metres[~inside | (readings == 0)] = np.nan
    return metres.astype(np.float32).reshape(points.shape[:-1])


def with_depth(
    frame: SkeletonFrame,
    depth_image: np.ndarray,
    scale_mm: float = 1.0,
    window: int = DEFAULT_WINDOW,
    keypoint_image_size: tuple[float, float] | None = None,
) -> SkeletonFrame:
    """A copy of ``frame`` whose depth is sampled from ``depth_image`` (keypoints unchanged)."""
    depth = sample_depth(depth_image, frame.keypoints, scale_mm, window, keypoint_image_size)
    return SkeletonFrame(frame.keypoints, depth, frame.timestamp, frame.floor)


def people_with_depth(
    observation: Observation,
    window: int = DEFAULT_WINDOW,
    keypoint_image_size: tuple[float, float] | None = None,
) -> list[SkeletonFrame]:
    """Everyone in ``observation`` with depth sampled from its depth image, in one vectorised
    call; without a depth image the people are returned as they are (depth the source knew, or
    NaN). Run it before tracking so the tracker can tell people apart by distance too."""
    people = observation.people
    if observation.depth_image is None or not people:
        return list(people)
    keypoints = np.stack([p.keypoints for p in people])
    depth = sample_depth(
        observation.depth_image, keypoints, observation.depth_scale_mm, window, keypoint_image_size
    )
    return [
        SkeletonFrame(p.keypoints, d, p.timestamp, p.floor)
        for p, d in zip(people, depth, strict=True)
    ]
