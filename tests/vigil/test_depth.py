"""Depth at keypoints, on the REAL URFD depth frames of fall-01 (Kwolek & Kepski, CC BY-NC-SA)."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from robot_agent.sources.replay import UrfdReplaySource
from vigil.datasets import urfd
from vigil.depth import people_with_depth, sample_depth, with_depth
from vigil.observation import Observation
from vigil.skeleton import SkeletonFrame

DEPTH_DIR = urfd.default_dir() / "depth"
SCALE = 6000 / 65535  # fall sequences


def reference_depth(image, keypoints, scale_mm, window=5):
    """Plain per-keypoint loop: what sample_depth must equal."""
    half = window // 2
    out = np.full(len(keypoints), np.nan)
    for i, (x, y, c) in enumerate(keypoints):
        col, row = int(np.floor(x)), int(np.floor(y))
        if c <= 0 or not (0 <= col < image.shape[1] and 0 <= row < image.shape[0]):
            continue
        rows = np.clip(np.arange(row - half, row + half + 1), 0, image.shape[0] - 1)
        cols = np.clip(np.arange(col - half, col + half + 1), 0, image.shape[1] - 1)
        patch = image[np.ix_(rows, cols)].ravel()
        patch = patch[patch > 0]
        if patch.size:
            out[i] = np.median(patch.astype(np.float64)) * scale_mm / 1000
    return out


@pytest.fixture(scope="module")
def urfd_frames():
    source = UrfdReplaySource("fall-01", speed=0, depth_dir=DEPTH_DIR)
    frames = [o for o in source if o.depth_image is not None]
    assert [o.index for o in frames] == [2, 10, 20, 30, 40, 50, 60, 70, 80, 90, 99]
    return frames


def test_real_frames_give_plausible_metres_and_follow_the_person(urfd_frames):
    medians = []
    for obs in urfd_frames:
        person = obs.people[0]
        depth = sample_depth(obs.depth_image, person.keypoints, obs.depth_scale_mm)
        present = person.present
        assert np.isfinite(depth[present]).all()  # every found keypoint lands on a reading
        assert np.isnan(depth[~present]).all()  # MoveNet has no eyes/feet: NaN, not 0
        assert ((depth[present] > 1.5) & (depth[present] < 6.0)).all()  # metres, Kinect range
        medians.append(float(np.median(depth[present])))
    # fall-01: the person walks towards the camera and falls about 3 m from it
    assert 4.0 < medians[0] < 5.0
    assert 2.3 < medians[-1] < 3.5
    assert medians[-1] < medians[0] - 1.0


def test_vectorised_equals_a_plain_loop_on_real_images(urfd_frames):
    rng = np.random.default_rng(0)
    for obs in urfd_frames:
        keypoints = obs.people[0].keypoints.copy()
        random = np.column_stack(
            [rng.uniform(-20, 660, 25), rng.uniform(-20, 500, 25), rng.uniform(-0.2, 1, 25)]
        ).astype(np.float32)
        for kp in (keypoints, random):
            for window in (1, 5, 9):
                expected = reference_depth(obs.depth_image, kp, SCALE, window)
                got = sample_depth(obs.depth_image, kp, SCALE, window)
                np.testing.assert_allclose(got, expected, rtol=1e-6, equal_nan=True)


def test_zeros_are_ignored_and_empty_windows_are_nan():
    image = cv2.imread(str(DEPTH_DIR / "fall-01-cam0-d-050.png"), cv2.IMREAD_UNCHANGED)
    assert image.dtype == np.uint16
    image = image.copy()
    image[100:105, 100:103] = 0  # 15 of the 25 pixels around (101, 102) read nothing
    image[100:105, 103:105] = 30000
    image[300:305, 300:305] = 0  # no reading at all around (302, 302)
    keypoints = np.zeros((25, 3), np.float32)
    keypoints[0] = (102.4, 102.7, 0.9)
    keypoints[1] = (302, 302, 0.9)
    keypoints[2] = (700, 10, 0.9)  # outside the image
    keypoints[3] = (200, 200, 0.0)  # missing
    depth = sample_depth(image, keypoints, SCALE)
    assert depth[0] == pytest.approx(30000 * SCALE / 1000, rel=1e-6)
    assert np.isnan(depth[1:]).all()


def test_scaled_keypoints_bad_input_and_batch():
    image = np.full((480, 640), 2000, np.uint16)
    image[:, 320:] = 4000
    keypoints = np.zeros((2, 25, 3), np.float32)
    keypoints[0, 0] = (100, 100, 1)  # in a 320x240 picture: (200, 200) of the depth image
    keypoints[1, 0] = (200, 100, 1)  # -> (400, 200)
    depth = sample_depth(image, keypoints, 1.0, keypoint_image_size=(320, 240))
    assert depth.shape == (2, 25)
    assert depth[0, 0] == pytest.approx(2.0) and depth[1, 0] == pytest.approx(4.0)
    frame = with_depth(SkeletonFrame(keypoints[0], timestamp=1.5), image, 1.0)
    assert frame.depth[0] == pytest.approx(2.0) and frame.timestamp == 1.5
    with pytest.raises(ValueError, match="integer"):
        sample_depth(image.astype(np.float32), keypoints)
    with pytest.raises(ValueError, match="odd"):
        sample_depth(image, keypoints, window=4)


def test_depth_dir_exists():
    assert Path(DEPTH_DIR).is_dir(), f"URFD depth frames missing at {DEPTH_DIR}"


def test_people_with_depth_samples_everyone_or_keeps_known_depth(urfd_frames):
    obs = urfd_frames[-1]
    person = obs.people[0]
    shifted = SkeletonFrame(person.keypoints.copy(), timestamp=person.timestamp)
    shifted.keypoints[person.present, 0] -= 150  # a second "person" further left
    obs = Observation(
        obs.timestamp,
        [person, shifted],
        depth_image=obs.depth_image,
        depth_scale_mm=obs.depth_scale_mm,
    )
    people = people_with_depth(obs)
    assert len(people) == 2
    for got, source in zip(people, obs.people, strict=True):
        expected = sample_depth(obs.depth_image, source.keypoints, obs.depth_scale_mm)
        np.testing.assert_array_equal(got.depth, expected)
        assert got.timestamp == source.timestamp
    known = SkeletonFrame(person.keypoints, np.full(25, 3.0, np.float32))
    assert people_with_depth(Observation(0.0, [known]))[0].depth[0] == 3.0
