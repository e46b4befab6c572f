"""The generated robot's camera: a Kinect-like pinhole (640x480 pixels, 30 frames/s, depth along
the optical axis in metres) on a known mount, and its noise, dropped keypoints and occlusion."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vigil.floor import CameraMount
from vigil.skeleton import INDEX, N_KEYPOINTS

FPS = 30.0
IMAGE_WIDTH, IMAGE_HEIGHT = 640, 480
FOCAL_PX = 525.0  # Kinect v1 colour/depth focal length at 640x480
CAMERA_HEIGHT_M = 1.0
CAMERA_TILT_RAD = math.radians(6.0)  # looking slightly down
#: The generated robot's depth camera, so generated frames carry floor measures (vigil.floor).
CAMERA_MOUNT = CameraMount(
    fx=FOCAL_PX,
    fy=FOCAL_PX,
    cx=IMAGE_WIDTH / 2,
    cy=IMAGE_HEIGHT / 2,
    height_m=CAMERA_HEIGHT_M,
    pitch_deg=math.degrees(CAMERA_TILT_RAD),
)
MIN_VISIBLE_KEYPOINTS = 5
MARKER_SIZE_M = 0.09  # ArUco marker worn on the patient's chest


def project(world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (..., 2) and depth along the optical axis (...,) in metres of world points."""
    rel = world - np.array([0.0, CAMERA_HEIGHT_M, 0.0])
    axis = np.array([0.0, -math.sin(CAMERA_TILT_RAD), math.cos(CAMERA_TILT_RAD)])
    cam_up = np.array([0.0, math.cos(CAMERA_TILT_RAD), math.sin(CAMERA_TILT_RAD)])
    depth = rel @ axis
    safe = np.where(depth > 0.05, depth, np.nan)
    u = IMAGE_WIDTH / 2 + FOCAL_PX * rel[..., 0] / safe
    v = IMAGE_HEIGHT / 2 - FOCAL_PX * (rel @ cam_up) / safe
    return np.stack([u, v], axis=-1), depth


@dataclass(frozen=True)
class CameraNoise:
    pixel_sigma: float = 1.5  # at 2.5 m; grows with distance
    drop_probability: float = 0.03  # per keypoint and frame, more at the extremities
    depth_sigma_per_m2: float = 0.004  # Kinect: depth noise grows with the square of distance
    depth_dropout: float = 0.03


_EXTREMITY_NAMES = (
    "r_wrist",
    "l_wrist",
    "l_big_toe",
    "l_small_toe",
    "l_heel",
    "r_big_toe",
    "r_small_toe",
    "r_heel",
    "r_ear",
    "l_ear",
)
_EXTREMITIES = np.array([INDEX[k] for k in _EXTREMITY_NAMES])


def render(
    world: np.ndarray, rng: np.random.Generator, noise: CameraNoise
) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints (T, 25, 3) and depth (T, 25) from world points, with camera noise."""
    px, depth = project(world)
    t = world.shape[0]
    dist = np.nan_to_num(depth, nan=10.0)
    sigma = noise.pixel_sigma * np.clip(2.5 / np.maximum(dist, 0.3), 0.5, 3.0)
    px = px + rng.normal(0, 1, px.shape) * sigma[..., None]
    conf = np.clip(0.9 - 0.05 * dist + rng.normal(0, 0.08, (t, N_KEYPOINTS)), 0.05, 0.99)
    drop_p = np.full(N_KEYPOINTS, noise.drop_probability)
    drop_p[_EXTREMITIES] *= 3
    dropped = rng.random((t, N_KEYPOINTS)) < drop_p
    outside = (
        ~np.isfinite(px).all(-1)
        | (px[..., 0] < 0)
        | (px[..., 0] >= IMAGE_WIDTH)
        | (px[..., 1] < 0)
        | (px[..., 1] >= IMAGE_HEIGHT)
        | ~(depth > 0.3)
    )
    missing = dropped | outside
    keypoints = np.concatenate([px, conf[..., None]], axis=-1).astype(np.float32)
    keypoints[missing] = 0.0
    measured = depth + rng.normal(0, 1, depth.shape) * noise.depth_sigma_per_m2 * dist**2
    measured = np.where(missing | (rng.random(depth.shape) < noise.depth_dropout), np.nan, measured)
    return keypoints, measured.astype(np.float32)


def occlude(
    front: np.ndarray, front_depth: np.ndarray, back: np.ndarray, back_depth: np.ndarray
) -> None:
    """Hide, in place, keypoints of ``back`` that lie inside the box of a nearer ``front``."""
    for t in range(front.shape[0]):
        f_present = front[t, :, 2] > 0
        b_present = back[t, :, 2] > 0
        if f_present.sum() < MIN_VISIBLE_KEYPOINTS or not b_present.any():
            continue
        if np.isnan(front_depth[t]).all() or np.isnan(back_depth[t]).all():
            continue
        if np.nanmedian(front_depth[t]) >= np.nanmedian(back_depth[t]):
            continue
        xy = front[t, f_present, :2]
        lo, hi = xy.min(0) - 8, xy.max(0) + 8
        inside = b_present & np.all((back[t, :, :2] >= lo) & (back[t, :, :2] <= hi), axis=-1)
        back[t, inside] = 0.0
        back_depth[t, inside] = np.nan
