import math

import numpy as np
import pytest

from vigil.floor import CameraMount, floor_measures, floor_measures_many
from vigil.skeleton import FLOOR_NEAR_M, N_KEYPOINTS
from vigil.synthetic import CAMERA_MOUNT, project


def _person(heights: np.ndarray, distance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints and depth of 25 points at the given heights, `distance_m` in front of the
    generator's camera (vigil.synthetic.project is the independent forward model)."""
    world = np.stack(
        [np.linspace(-0.2, 0.2, N_KEYPOINTS), heights, np.full(N_KEYPOINTS, distance_m)], axis=1
    )
    pixels, depth = project(world)
    keypoints = np.concatenate([pixels, np.ones((N_KEYPOINTS, 1))], axis=1)
    return keypoints.astype(np.float32), depth.astype(np.float32)


def test_heights_above_the_floor_are_recovered_from_pixels_and_depth():
    heights = np.linspace(0.05, 1.65, N_KEYPOINTS)
    keypoints, depth = _person(heights, 3.0)
    recovered = CAMERA_MOUNT.heights(keypoints, depth)
    assert np.allclose(recovered, heights, atol=1e-4)
    top, centre, near = floor_measures(keypoints, depth, CAMERA_MOUNT)
    assert top == pytest.approx(1.65, abs=1e-4)
    assert centre == pytest.approx(heights.mean(), abs=1e-4)
    assert near == pytest.approx(np.mean(heights < FLOOR_NEAR_M))


def test_a_person_lying_on_the_floor_is_near_it_and_one_on_a_bed_is_not():
    floor_person = _person(np.full(N_KEYPOINTS, 0.15), 2.5)
    bed_person = _person(np.full(N_KEYPOINTS, 0.65), 2.5)
    on_floor = floor_measures(*floor_person, CAMERA_MOUNT)
    on_bed = floor_measures(*bed_person, CAMERA_MOUNT)
    assert on_floor[2] == 1.0 and on_bed[2] == 0.0
    assert on_floor[0] < 0.2 < 0.6 < on_bed[0]


def test_missing_keypoints_and_unknown_depth_are_left_out_and_too_few_give_nan():
    keypoints, depth = _person(np.linspace(0.1, 1.7, N_KEYPOINTS), 3.0)
    keypoints[:20, 2] = 0.0  # missing: their positions must not count
    depth[20] = np.nan
    top, _, _ = floor_measures(keypoints, depth, CAMERA_MOUNT)
    assert top == pytest.approx(1.7, abs=1e-4)
    depth[21:23] = np.nan  # only 2 keypoints with depth remain
    assert np.isnan(floor_measures(keypoints, depth, CAMERA_MOUNT)).all()
    many = floor_measures_many(np.stack([keypoints] * 3), np.stack([depth] * 3), CAMERA_MOUNT)
    assert many.shape == (3, 3) and np.isnan(many).all()


def test_a_level_camera_needs_no_tilt_correction():
    mount = CameraMount(fx=500, fy=500, cx=320, cy=240, height_m=1.2, pitch_deg=0.0)
    keypoints = np.zeros((N_KEYPOINTS, 3), np.float32)
    keypoints[:, 1] = 240 + 500 * 1.2 / 4.0  # every point on the floor, 4 m away
    keypoints[:, 2] = 1.0
    depth = np.full(N_KEYPOINTS, 4.0, np.float32)
    assert np.allclose(mount.heights(keypoints, depth), 0.0, atol=1e-6)


@pytest.mark.parametrize(
    ("field", "value"), [("fx", 0.0), ("fy", -1.0), ("height_m", math.nan), ("pitch_deg", 95.0)]
)
def test_an_impossible_mount_is_refused_naming_the_field(field, value):
    values = {"fx": 500, "fy": 500, "cx": 320, "cy": 240, "height_m": 1.0, "pitch_deg": 5.0}
    with pytest.raises(ValueError, match=field):
        CameraMount(**{**values, field: value})
