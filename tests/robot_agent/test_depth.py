"""Depth at keypoints on the real URFD depth PNGs (fall-01, camera 0)."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from robot_agent.depth import URFD_FALL_MM_PER_UNIT, sample_depth
from vigil.datasets.urfd import default_dir

DEPTH_DIR = default_dir() / "depth"


def _frames() -> list[Path]:
    files = sorted(DEPTH_DIR.glob("fall-01-cam0-d-*.png"))
    if not files:
        pytest.fail(f"URFD depth PNGs missing in {DEPTH_DIR}")
    return files


def test_real_depth_png_gives_metres_in_a_room_range():
    image = cv2.imread(str(_frames()[0]), cv2.IMREAD_UNCHANGED)
    assert image.dtype == np.uint16 and image.shape == (480, 640)
    ys, xs = np.nonzero(image)
    pick = np.linspace(0, len(xs) - 1, 25).astype(int)
    keypoints = np.stack([xs[pick], ys[pick], np.ones(25)], axis=1).astype(np.float32)
    depth = sample_depth(image, keypoints, URFD_FALL_MM_PER_UNIT)
    assert np.isfinite(depth).all()
    assert 0.4 < np.median(depth) < 6.0  # a room seen by a Kinect, in metres
    # the median of the window, zeros ignored, converted P * 6000 / 65535 mm -> m
    window = image[ys[pick[3]] - 2 : ys[pick[3]] + 3, xs[pick[3]] - 2 : xs[pick[3]] + 3]
    nonzero = window[window > 0]
    assert depth[3] == pytest.approx(np.median(nonzero) * 6000 / 65535 / 1000, rel=1e-5)


def test_zeros_missing_keypoints_and_outside_points_are_nan():
    image = cv2.imread(str(_frames()[-1]), cv2.IMREAD_UNCHANGED)
    ys, xs = np.nonzero(image == 0)
    assert len(xs), "the real frames have pixels without a reading"
    holes = np.zeros((25, 3), np.float32)
    holes[:, 2] = 1
    big_hole = None
    for x, y in zip(xs, ys, strict=False):  # a pixel whose whole 5x5 window reads 0
        if 2 <= x < 637 and 2 <= y < 477 and not image[y - 2 : y + 3, x - 2 : x + 3].any():
            big_hole = (x, y)
            break
    assert big_hole is not None
    holes[0, :2] = big_hole
    holes[1, :2] = (700, 10)  # outside the image
    holes[2, :] = (320, 240, 0)  # keypoint missing
    holes[3:, :2] = (320, 240)
    depth = sample_depth(image, holes, URFD_FALL_MM_PER_UNIT)
    assert np.isnan(depth[:3]).all()


def test_a_single_zero_in_the_window_is_ignored_not_averaged():
    image = np.full((20, 20), 1000, np.uint16)
    image[10, 10] = 0
    depth = sample_depth(image, np.array([[10, 10, 1.0]] * 25, np.float32), mm_per_unit=1.0)
    assert depth[0] == pytest.approx(1.0)
