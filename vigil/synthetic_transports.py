"""GENERATED transports (not real data) for the classes URFD lacks: wheelchair and combined modes.

A kinematic stick figure (BODY_25, frontal camera on the robot) runs through scripted situations:
each segment has a fine label from the taxonomy and a target pose reached over a transition time.
Camera noise, dropped keypoints (confidence 0), per-keypoint depth in metres and distance changes
are added. Everything produced here is labelled `generated`; it is for demos, load tests and
exercising the wheelchair/combined pipelines end to end, never for claims about real accuracy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vigil.classes import MODE_CLASSES, TransportMode
from vigil.skeleton import INDEX, N_KEYPOINTS
from vigil.taxonomy import DEFAULT_TAXONOMY, Taxonomy

GENERATED = True
FPS = 15.0
IMAGE_SIZE = (640.0, 480.0)
FOCAL_PX = 500.0
CAMERA_HEIGHT_M = 1.0
BODY_HEIGHT_M = 1.7

# Standing pose, frontal view, in body heights: x lateral (right of image +), y up from floor.
_STANDING = {
    "nose": (0, 0.93), "neck": (0, 0.82), "r_shoulder": (-0.12, 0.81), "r_elbow": (-0.15, 0.64),
    "r_wrist": (-0.16, 0.48), "l_shoulder": (0.12, 0.81), "l_elbow": (0.15, 0.64),
    "l_wrist": (0.16, 0.48), "mid_hip": (0, 0.52), "r_hip": (-0.06, 0.52),
    "r_knee": (-0.07, 0.29), "r_ankle": (-0.07, 0.05), "l_hip": (0.06, 0.52),
    "l_knee": (0.07, 0.29), "l_ankle": (0.07, 0.05), "r_eye": (-0.02, 0.95),
    "l_eye": (0.02, 0.95), "r_ear": (-0.05, 0.94), "l_ear": (0.05, 0.94),
    "l_big_toe": (0.09, 0.0), "l_small_toe": (0.11, 0.0), "l_heel": (0.06, 0.01),
    "r_big_toe": (-0.09, 0.0), "r_small_toe": (-0.11, 0.0), "r_heel": (-0.06, 0.01),
}  # fmt: skip
_UPPER = [INDEX[k] for k in ("nose", "neck", "r_shoulder", "r_elbow", "r_wrist", "l_shoulder",
                             "l_elbow", "l_wrist", "r_eye", "l_eye", "r_ear", "l_ear")]  # fmt: skip


def _standing() -> np.ndarray:
    pose = np.zeros((N_KEYPOINTS, 2))
    for name, xy in _STANDING.items():
        pose[INDEX[name]] = xy
    return pose


def _rotate(pose: np.ndarray, indices, centre: np.ndarray, degrees: float) -> np.ndarray:
    pose = pose.copy()
    a = np.radians(degrees)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    pose[indices] = (pose[indices] - centre) @ rot.T + centre
    return pose


def _sitting() -> np.ndarray:
    pose = _standing()
    upper = _UPPER + [INDEX["mid_hip"], INDEX["r_hip"], INDEX["l_hip"]]
    pose[upper, 1] -= 0.22
    pose[[INDEX["r_knee"], INDEX["l_knee"]], 1] = 0.27
    pose[[INDEX["r_knee"], INDEX["l_knee"]], 0] *= 1.6
    return pose


def _template(name: str, rng: np.random.Generator) -> np.ndarray:
    side = rng.choice([-1.0, 1.0])
    if name == "standing":
        return _standing()
    if name == "sitting":
        return _sitting()
    if name == "slumped":
        pose = _sitting()
        pose = _rotate(pose, _UPPER, pose[INDEX["mid_hip"]], side * rng.uniform(25, 45))
        pose[[INDEX["nose"], INDEX["r_eye"], INDEX["l_eye"]], 1] -= 0.08
        return pose
    if name == "lying":
        pose = _rotate(_standing(), list(range(N_KEYPOINTS)), np.zeros(2), side * 90)
        pose[:, 1] += 0.05 - pose[:, 1].min()
        return pose
    if name == "lying_bed":
        pose = _template("lying", rng)
        pose[:, 1] += 0.3
        return pose
    if name == "half_up":
        return (_sitting() + _standing()) / 2
    if name == "arm_out":
        pose = _sitting()
        for part, reach in (("elbow", 0.33), ("wrist", 0.5)):
            key = f"{'l' if side > 0 else 'r'}_{part}"
            pose[INDEX[key]] = (side * reach, 0.55 - 0.03 * (part == "wrist"))
        return pose
    if name == "leg_out":
        pose = _sitting()
        for part, reach in (("knee", 0.3), ("ankle", 0.45)):
            key = f"{'l' if side > 0 else 'r'}_{part}"
            pose[INDEX[key]] = (side * reach, 0.2)
        return pose
    if name == "stumble":
        pose = _rotate(_standing(), _UPPER, np.array([0, 0.52]), side * rng.uniform(20, 35))
        pose[[INDEX["r_wrist"], INDEX["l_wrist"]], 0] *= 2.5
        pose[[INDEX["r_wrist"], INDEX["l_wrist"]], 1] += 0.2
        return pose
    if name == "bending":
        pose = _standing()
        pose[_UPPER, 1] -= 0.25
        return pose
    if name == "kneeling":
        pose = _standing()
        pose[_UPPER + [INDEX["mid_hip"], INDEX["r_hip"], INDEX["l_hip"]], 1] -= 0.25
        pose[INDEX["r_knee"], 1] = 0.04
        return pose
    if name == "sitting_floor":
        pose = _sitting()
        pose[:, 1] -= 0.22
        pose[:, 1] = np.maximum(pose[:, 1], 0.02)
        return pose
    raise ValueError(f"unknown pose template {name!r}")


# A segment: (fine label, pose template, transition s, (min, max) duration s, distance change m).
Segment = tuple[str, str, float, tuple[float, float], float]
_WHEELCHAIR: dict[str, list[Segment]] = {
    "ride": [("sitting_wheelchair", "sitting", 0.0, (6, 10), 0.0)],
    "gesture": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 4), 0.0),
        ("gesturing", "arm_out", 0.5, (0.3, 0.6), 0.0),
        ("sitting_wheelchair", "sitting", 0.5, (2, 4), 0.0),
    ],
    "slump": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 5), 0.0),
        ("slumped_unconscious_wheelchair", "slumped", 1.5, (3, 5), 0.0),
    ],
    "fall_out": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 5), 0.0),
        ("falling_out_of_wheelchair", "lying", 0.8, (0.8, 0.8), 0.0),
        ("lying_on_floor", "lying", 0.0, (2, 4), 0.0),
    ],
    "stand_up": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 4), 0.0),
        ("standing_up_from_wheelchair", "standing", 1.5, (2, 3), 0.0),
        ("sitting_down", "sitting", 1.5, (2, 3), 0.0),
    ],
    "arm_out": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 4), 0.0),
        ("crushing_hazard", "arm_out", 0.6, (1.5, 3), 0.0),
        ("sitting_wheelchair", "sitting", 0.6, (2, 3), 0.0),
    ],
    "leg_out": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 4), 0.0),
        ("crushing_hazard", "leg_out", 0.6, (1.5, 3), 0.0),
        ("sitting_wheelchair", "sitting", 0.6, (2, 3), 0.0),
    ],
    "too_far": [
        ("sitting_wheelchair", "sitting", 0.0, (2, 3), 0.0),
        ("too_far_away", "sitting", 2.0, (3, 5), 3.5),
    ],
}
_WALKING: dict[str, list[Segment]] = {
    "walk": [("walking", "standing", 0.0, (6, 10), 0.0)],
    "rollator": [("walking_rollator", "standing", 0.0, (6, 10), 0.0)],
    "turn_bend": [
        ("walking", "standing", 0.0, (2, 4), 0.0),
        ("bending", "bending", 1.0, (1, 2), 0.0),
        ("standing", "standing", 1.0, (2, 3), 0.0),
    ],
    "kneel": [
        ("walking", "standing", 0.0, (2, 4), 0.0),
        ("kneeling", "kneeling", 1.2, (2, 3), 0.0),
        ("standing", "standing", 1.2, (2, 3), 0.0),
    ],
    "lie_down": [
        ("standing", "standing", 0.0, (2, 4), 0.0),
        ("lying_down_deliberately", "lying_bed", 3.0, (5, 7), 0.0),
    ],
    "fall": [
        ("walking", "standing", 0.0, (2, 5), 0.0),
        ("falling", "lying", 0.7, (0.7, 0.7), 0.0),
        ("lying_on_floor", "lying", 0.0, (2, 4), 0.0),
    ],
    "stumble": [
        ("walking", "standing", 0.0, (2, 4), 0.0),
        ("stumbling", "stumble", 0.3, (0.6, 1.0), 0.0),
        ("walking", "standing", 0.5, (2, 3), 0.0),
    ],
    "fall_sit": [
        ("walking_rollator", "standing", 0.0, (2, 4), 0.0),
        ("stumbling_rollator", "stumble", 0.3, (0.5, 0.5), 0.0),
        ("sitting_on_floor_after_fall", "sitting_floor", 0.6, (2, 3), 0.0),
        ("trying_to_get_up", "half_up", 1.5, (2, 3), 0.0),
    ],
}


@dataclass(frozen=True, slots=True)
class GeneratedSequence:
    name: str
    keypoints: np.ndarray  # (n, 25, 3) pixels of a 640x480 image
    depth: np.ndarray  # (n, 25) metres, NaN where unknown
    timestamps: np.ndarray  # (n,)
    fine_labels: tuple[str, ...]
    generated: bool = True


def _scenarios(mode: TransportMode) -> dict[str, list[Segment]]:
    if mode == TransportMode.WHEELCHAIR:
        return _WHEELCHAIR
    if mode == TransportMode.COMBINED:
        return {**_WHEELCHAIR, **{f"walk_{k}": v for k, v in _WALKING.items()}}
    return _WALKING


def generate_sequence(
    scenario: list[Segment], rng: np.random.Generator, name: str, fps: float = FPS
) -> GeneratedSequence:
    poses, labels, distances = [], [], []
    current = _template(scenario[0][1], rng)
    distance = rng.uniform(1.5, 2.5)
    for label, template, transition, (lo, hi), distance_change in scenario:
        target = _template(template, rng)
        target_distance = distance + distance_change
        frames = max(int(round(rng.uniform(lo, hi) * fps)), 1)
        ramp = max(int(round(transition * fps)), 1)
        for i in range(frames):
            w = min((i + 1) / ramp, 1.0)
            w = w * w * (3 - 2 * w)  # smooth start and stop
            poses.append((1 - w) * current + w * target)
            distances.append((1 - w) * distance + w * target_distance)
            labels.append(label)
        current, distance = target, target_distance
    n = len(poses)
    t = np.arange(n) / fps
    body = np.stack(poses) * BODY_HEIGHT_M  # metres
    sway = 0.02 * np.sin(2 * np.pi * rng.uniform(0.5, 1.0) * t)[:, None]
    body[:, :, 0] += sway + rng.uniform(-0.3, 0.3)
    dist = np.array(distances)[:, None]
    x = IMAGE_SIZE[0] / 2 + FOCAL_PX * body[:, :, 0] / dist
    y = IMAGE_SIZE[1] / 2 - FOCAL_PX * (body[:, :, 1] - CAMERA_HEIGHT_M) / dist
    noise = rng.normal(0, 2.0, (n, N_KEYPOINTS, 2))
    keypoints = np.concatenate([np.stack([x, y], axis=2) + noise, np.ones((n, N_KEYPOINTS, 1))], 2)
    keypoints[:, :, 2] = rng.uniform(0.4, 1.0, (n, N_KEYPOINTS))
    dropped = rng.random((n, N_KEYPOINTS)) < 0.05
    keypoints[dropped] = 0.0
    depth = np.broadcast_to(dist, (n, N_KEYPOINTS)) + rng.normal(0, 0.03, (n, N_KEYPOINTS))
    depth = np.where(dropped | (rng.random((n, N_KEYPOINTS)) < 0.05), np.nan, depth)
    return GeneratedSequence(
        name, keypoints.astype(np.float32), depth.astype(np.float32), t, tuple(labels)
    )


def generate_transports(
    mode: TransportMode | str, repeats: int = 8, seed: int = 0
) -> list[GeneratedSequence]:
    """`repeats` randomised sequences of every scenario of the mode (GENERATED data)."""
    mode = TransportMode(mode)
    rng = np.random.default_rng(seed)
    return [
        generate_sequence(segments, rng, f"gen-{mode.value}-{key}-{r:02d}")
        for key, segments in _scenarios(mode).items()
        for r in range(repeats)
    ]


def class_targets(
    sequence: GeneratedSequence, mode: TransportMode | str, taxonomy: Taxonomy = DEFAULT_TAXONOMY
) -> np.ndarray:
    """Class index (in MODE_CLASSES[mode] order) of every frame."""
    mode = TransportMode(mode)
    classes = MODE_CLASSES[mode]
    return np.array([classes.index(taxonomy.decision(k, mode)) for k in sequence.fine_labels])
