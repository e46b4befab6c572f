"""GENERATED transports: PeTRA-like patient transports rendered as BODY_25 keypoints.

Everything this module produces is generated data (``GeneratedTransport.generated`` is always
True), meant for demos, load tests and the classes URFD lacks; never for claims about
detection quality.

A small kinematic body (pelvis position, trunk yaw/pitch/roll, hip, knee, shoulder and elbow
angles) is animated activity by activity, each activity carrying one fine label of
``vigil.taxonomy``, then projected through a Kinect-like pinhole camera on the robot
(640x480 pixels, 30 frames/s, depth along the optical axis in metres) with camera noise,
dropped keypoints, occlusion and 0-4 bystanders crossing the view. The same seed always
gives the same transport.

``GeneratedTransport.patient_sequence()`` gives the patient alone as plain arrays
(``GeneratedSequence``) and ``class_targets`` their class per frame in a mode.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.floor import CameraMount, floor_measures_many
from vigil.skeleton import INDEX, N_FLOOR, N_KEYPOINTS, SkeletonFrame
from vigil.taxonomy import DEFAULT_TAXONOMY, Taxonomy


@dataclass(frozen=True)
class GeneratedSequence:
    """One GENERATED patient's frames as arrays."""

    name: str
    keypoints: np.ndarray  # (n, 25, 3) pixels of a 640x480 image
    depth: np.ndarray  # (n, 25) metres, NaN where unknown
    timestamps: np.ndarray  # (n,)
    fine_labels: tuple[str, ...]
    generated: bool = True
    floor: np.ndarray | None = None  # (n, 3) floor measures (vigil.floor), NaN where unknown


def class_targets(
    sequence: GeneratedSequence, mode: TransportMode | str, taxonomy: Taxonomy = DEFAULT_TAXONOMY
) -> np.ndarray:
    """Class index (in MODE_CLASSES[mode] order) of every frame."""
    mode = TransportMode(mode)
    classes = MODE_CLASSES[mode]
    return np.array([classes.index(taxonomy.decision(k, mode)) for k in sequence.fine_labels])


FPS = 30.0
IMAGE_WIDTH, IMAGE_HEIGHT = 640, 480
FOCAL_PX = 525.0  # Kinect v1 colour/depth focal length at 640x480
CAMERA_HEIGHT_M = 1.0
CAMERA_TILT_RAD = math.radians(6.0)  # looking slightly down
#: The generated robot's depth camera, so generated frames carry floor measures (vigil.floor).
CAMERA_MOUNT = CameraMount(
    fx=FOCAL_PX, fy=FOCAL_PX, cx=IMAGE_WIDTH / 2, cy=IMAGE_HEIGHT / 2,
    height_m=CAMERA_HEIGHT_M, pitch_deg=math.degrees(CAMERA_TILT_RAD),
)  # fmt: skip
MIN_VISIBLE_KEYPOINTS = 5
MARKER_SIZE_M = 0.09  # ArUco marker worn on the patient's chest


class Locomotion(StrEnum):
    """How the patient moves during the transport (the generator's 'mode')."""

    WALKING = "walking"
    ROLLATOR = "rollator"
    WHEELCHAIR = "wheelchair"

    @property
    def transport_mode(self) -> TransportMode:
        return TransportMode.WHEELCHAIR if self is Locomotion.WHEELCHAIR else TransportMode.WALKING


# --------------------------------------------------------------------------------------------
# Body parameters
# --------------------------------------------------------------------------------------------

PARAMS: tuple[str, ...] = (
    "x", "z", "pelvis_h", "yaw", "pitch", "roll", "head_pitch",
    "hip_flex_r", "hip_flex_l", "knee_r", "knee_l", "hip_abd_r", "hip_abd_l",
    "sh_flex_r", "sh_flex_l", "sh_abd_r", "sh_abd_l", "elbow_r", "elbow_l",
)  # fmt: skip
P = {name: i for i, name in enumerate(PARAMS)}

STAND: dict[str, float] = {"pelvis_h": 0.95, "sh_abd_r": 0.08, "sh_abd_l": 0.08, "elbow_r": 0.1,
                           "elbow_l": 0.1}  # fmt: skip
SIT_WHEELCHAIR: dict[str, float] = {
    "pelvis_h": 0.52, "hip_flex_r": 1.5, "hip_flex_l": 1.5, "knee_r": 1.45, "knee_l": 1.45,
    "sh_flex_r": 0.35, "sh_flex_l": 0.35, "sh_abd_r": 0.25, "sh_abd_l": 0.25,
    "elbow_r": 1.2, "elbow_l": 1.2, "pitch": 0.05,
}  # fmt: skip


def _pose(base: np.ndarray, scale: float, **overrides: float) -> np.ndarray:
    """A parameter vector: ``base`` with the body-posture entries replaced (heights scaled)."""
    out = base.copy()
    for key in PARAMS[2:]:
        out[P[key]] = 0.0
    for key, value in {**STAND, **overrides}.items():
        out[P[key]] = value * scale if key == "pelvis_h" else value
    return out


# --------------------------------------------------------------------------------------------
# Forward kinematics and projection
# --------------------------------------------------------------------------------------------


def _limb(flex: np.ndarray, abd: np.ndarray, side: float) -> np.ndarray:
    """Unit vector (T, 3) in body coordinates (right, up, forward) of a limb hanging down,
    rotated forward by ``flex`` and outward by ``abd``."""
    return np.stack(
        [side * np.sin(abd), -np.cos(abd) * np.cos(flex), np.cos(abd) * np.sin(flex)], axis=-1
    )


def _rotations(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(T, 3, 3) body->world rotation. World: x image-right, y up, z away from the camera.
    Body: x the person's right, y up, z the person's front; yaw 0 faces the camera."""
    t = len(yaw)
    c, s = np.cos, np.sin
    ry = np.zeros((t, 3, 3))
    ry[:, 0, 0], ry[:, 0, 2], ry[:, 1, 1] = c(yaw), s(yaw), 1
    ry[:, 2, 0], ry[:, 2, 2] = -s(yaw), c(yaw)
    rx = np.zeros((t, 3, 3))  # pitch: lean forward (up towards front)
    rx[:, 0, 0], rx[:, 1, 1], rx[:, 1, 2] = 1, c(pitch), -s(pitch)
    rx[:, 2, 1], rx[:, 2, 2] = s(pitch), c(pitch)
    rz = np.zeros((t, 3, 3))  # roll: lean towards the person's right
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0] = c(roll), s(roll), -s(roll)
    rz[:, 1, 1], rz[:, 2, 2] = c(roll), 1
    facing_camera = np.diag([-1.0, 1.0, -1.0])
    return facing_camera @ ry @ rx @ rz


def body_points(params: np.ndarray, scale: float) -> np.ndarray:
    """World positions (T, 25, 3) in metres of the BODY_25 keypoints."""
    t = params.shape[0]
    g = {name: params[:, i] for i, name in enumerate(PARAMS)}
    right = np.array([1.0, 0, 0])
    up = np.array([0, 1.0, 0])
    front = np.array([0, 0, 1.0])
    local = np.zeros((t, N_KEYPOINTS, 3))

    def put(name: str, value: np.ndarray) -> None:
        local[:, INDEX[name]] = value

    neck = np.broadcast_to(up * 0.52 * scale, (t, 3))
    head_dir = np.stack([np.zeros(t), np.cos(g["head_pitch"]), np.sin(g["head_pitch"])], -1)
    nose = neck + head_dir * 0.2 * scale + front * 0.07 * scale
    put("mid_hip", np.zeros((t, 3)))
    put("neck", neck)
    put("nose", nose)
    put("r_eye", nose + (up * 0.03 + right * 0.035 - front * 0.02) * scale)
    put("l_eye", nose + (up * 0.03 - right * 0.035 - front * 0.02) * scale)
    put("r_ear", nose + (right * 0.075 - front * 0.09) * scale)
    put("l_ear", nose + (-right * 0.075 - front * 0.09) * scale)
    for side, sign in (("r", 1.0), ("l", -1.0)):
        shoulder = neck + right * sign * 0.19 * scale
        flex, abd = g[f"sh_flex_{side}"], g[f"sh_abd_{side}"]
        elbow = shoulder + _limb(flex, abd, sign) * 0.3 * scale
        wrist = elbow + _limb(flex + g[f"elbow_{side}"], abd, sign) * 0.27 * scale
        put(f"{side}_shoulder", shoulder)
        put(f"{side}_elbow", elbow)
        put(f"{side}_wrist", wrist)
        hip = np.broadcast_to(right * sign * 0.1 * scale, (t, 3))
        hflex, habd = g[f"hip_flex_{side}"], g[f"hip_abd_{side}"]
        knee = hip + _limb(hflex, habd, sign) * 0.45 * scale
        ankle = knee + _limb(hflex - g[f"knee_{side}"], habd, sign) * 0.43 * scale
        put(f"{side}_hip", hip)
        put(f"{side}_knee", knee)
        put(f"{side}_ankle", ankle)
        put(f"{side}_big_toe", ankle + (front * 0.16 + right * sign * 0.02 - up * 0.05) * scale)
        put(f"{side}_small_toe", ankle + (front * 0.13 + right * sign * 0.06 - up * 0.05) * scale)
        put(f"{side}_heel", ankle + (-front * 0.05 - up * 0.06) * scale)
    rot = _rotations(g["yaw"], g["pitch"], g["roll"])
    pelvis = np.stack([g["x"], g["pelvis_h"], g["z"]], axis=-1)
    return np.einsum("tij,tkj->tki", rot, local) + pelvis[:, None, :]


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


# --------------------------------------------------------------------------------------------
# Activities: each appends (label, parameters) segments that continue from the last pose
# --------------------------------------------------------------------------------------------


def _smooth(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return s * s * (3 - 2 * s)


def _accelerating(n: int) -> np.ndarray:
    return np.linspace(0.0, 1.0, n) ** 2  # gravity: slow start, fast end


@dataclass
class _Builder:
    rng: np.random.Generator
    scale: float
    locomotion: Locomotion
    follow_z: float
    segments: list[tuple[str, np.ndarray]] = field(default_factory=list)
    gait_phase: float = 0.0

    @property
    def last(self) -> np.ndarray:
        return self.segments[-1][1][-1].copy()

    def frames(self, seconds: float) -> int:
        return max(2, round(seconds * FPS))

    def add(self, label: str, params: np.ndarray) -> None:
        self.segments.append((label, params))

    def move(
        self,
        label: str,
        target: np.ndarray,
        seconds: float,
        easing: Callable[[int], np.ndarray] = _smooth,
    ) -> None:
        n = self.frames(seconds)
        start = self.last
        w = easing(n)[:, None]
        self.add(label, start + (target - start) * w)

    def hold(self, label: str, seconds: float, jitter: float = 0.01) -> None:
        n = self.frames(seconds)
        base = np.repeat(self.last[None, :], n, axis=0)
        t = np.arange(n) / FPS
        drift = np.sin(2 * np.pi * 0.25 * t + self.rng.uniform(0, 6.3))
        base[:, P["pitch"]] += jitter * drift
        base[:, P["head_pitch"]] += 2 * jitter * drift
        self.add(label, base)

    def gait(
        self,
        label: str,
        seconds: float,
        amplitude: float = 0.35,
        arm_swing: float = 0.3,
        irregular: float = 0.0,
        z_target: float | None = None,
    ) -> None:
        n = self.frames(seconds)
        base = np.repeat(self.last[None, :], n, axis=0)
        step_hz = self.rng.uniform(0.8, 1.0) * (1.3 if irregular else 1.0)
        phase = self.gait_phase + 2 * np.pi * step_hz * np.arange(n) / FPS
        if irregular:
            phase = phase + irregular * np.sin(phase * 1.7 + self.rng.uniform(0, 6.3))
        self.gait_phase = float(phase[-1])
        swing = np.sin(phase)
        base[:, P["hip_flex_r"]] += amplitude * swing
        base[:, P["hip_flex_l"]] -= amplitude * swing
        base[:, P["knee_r"]] += 1.6 * amplitude * np.clip(-np.cos(phase), 0, None)
        base[:, P["knee_l"]] += 1.6 * amplitude * np.clip(np.cos(phase), 0, None)
        base[:, P["sh_flex_r"]] -= arm_swing * swing
        base[:, P["sh_flex_l"]] += arm_swing * swing
        base[:, P["pelvis_h"]] += 0.015 * self.scale * np.cos(2 * phase)
        base[:, P["x"]] += 0.03 * np.sin(phase)
        if irregular:
            wobble = np.sin(2 * np.pi * 2.2 * np.arange(n) / FPS)
            base[:, P["pitch"]] += 0.18 * irregular * (1 + wobble)
            base[:, P["roll"]] += 0.12 * irregular * wobble
            base[:, P["sh_abd_r"]] += 0.7 * irregular * np.abs(wobble)
            base[:, P["sh_abd_l"]] += 0.7 * irregular * np.abs(wobble)
        if z_target is not None:
            base[:, P["z"]] += (z_target - base[0, P["z"]]) * _smooth(n)
        self.add(label, base)


def _upright(b: _Builder) -> np.ndarray:
    if b.locomotion is Locomotion.ROLLATOR:
        return _pose(b.last, b.scale, pitch=0.25, sh_flex_r=0.75, sh_flex_l=0.75, elbow_r=0.7,
                     elbow_l=0.7, sh_abd_r=0.1, sh_abd_l=0.1)  # fmt: skip
    return _pose(b.last, b.scale)


def _base(b: _Builder, seconds: float) -> None:
    """The normal state of the transport: walking (with or without rollator) or sitting."""
    if b.locomotion is Locomotion.WHEELCHAIR:
        b.hold("sitting_wheelchair", seconds, jitter=0.02)
        return
    label = "walking_rollator" if b.locomotion is Locomotion.ROLLATOR else "walking"
    amplitude = 0.22 if b.locomotion is Locomotion.ROLLATOR else 0.35
    b.gait(label, seconds, amplitude=amplitude,
           arm_swing=0.05 if b.locomotion is Locomotion.ROLLATOR else 0.3,
           z_target=b.follow_z + b.rng.uniform(-0.15, 0.15))  # fmt: skip


def _lying_pose(b: _Builder) -> np.ndarray:
    direction = b.rng.choice(["side", "side", "forward", "backward"])
    sign = b.rng.choice([-1.0, 1.0])
    roll = sign * b.rng.uniform(1.3, 1.5) if direction == "side" else sign * 0.2
    pitch = {"side": 0.1, "forward": 1.45, "backward": -1.45}[str(direction)]
    return _pose(b.last, b.scale, pelvis_h=0.12, roll=roll, pitch=pitch, sh_abd_r=1.1,
                 sh_abd_l=0.9, hip_flex_r=0.3, knee_r=0.4, elbow_r=0.4, elbow_l=0.6)  # fmt: skip


def _fall_to_floor(b: _Builder, first_label: str) -> None:
    """falling (or falling_out_of_wheelchair) -> impact -> lying_on_floor."""
    lying = _lying_pose(b)
    b.move(first_label, lying, b.rng.uniform(0.45, 0.8), easing=_accelerating)
    n = b.frames(b.rng.uniform(0.15, 0.3))
    bounce = np.repeat(b.last[None, :], n, axis=0)
    decay = np.exp(-np.arange(n) / 3.0)
    bounce[:, P["pelvis_h"]] += 0.04 * b.scale * decay * np.abs(np.sin(np.arange(n) * 1.3))
    bounce[:, P["sh_abd_r"]] += 0.3 * decay
    b.add("impact", bounce)
    b.hold("lying_on_floor", b.rng.uniform(2.0, 5.0), jitter=0.005)


def _get_up(
    b: _Builder, final: np.ndarray, final_label: str, sit_first: bool | None = None
) -> None:
    if sit_first is None:
        sit_first = bool(b.rng.random() < 0.6)
    if sit_first:
        sit = _pose(b.last, b.scale, pelvis_h=0.12, hip_flex_r=1.45, hip_flex_l=1.45, knee_r=0.5,
                    knee_l=0.3, pitch=0.2, sh_flex_r=0.5, sh_flex_l=0.4)  # fmt: skip
        b.move("sitting_on_floor_after_fall", sit, b.rng.uniform(1.0, 1.8))
        b.hold("sitting_on_floor_after_fall", b.rng.uniform(1.0, 2.5), jitter=0.02)
    kneel = _pose(b.last, b.scale, pelvis_h=0.45, pitch=1.2, hip_flex_r=1.4, hip_flex_l=1.4,
                  knee_r=1.9, knee_l=1.9, sh_flex_r=1.3, sh_flex_l=1.3)  # fmt: skip
    for _ in range(int(b.rng.integers(1, 3))):  # failed attempts
        b.move("trying_to_get_up", kneel, b.rng.uniform(0.8, 1.3))
        down = _pose(b.last, b.scale, pelvis_h=0.2, pitch=1.3, hip_flex_r=1.2, hip_flex_l=1.2,
                     knee_r=1.7, knee_l=1.7, sh_flex_r=1.4, sh_flex_l=1.4)  # fmt: skip
        b.move("trying_to_get_up", down, b.rng.uniform(0.5, 0.9))
    b.move("trying_to_get_up", kneel, b.rng.uniform(0.8, 1.2))
    half = (b.last + final) / 2
    b.move("trying_to_get_up", half, b.rng.uniform(0.8, 1.2))
    b.move(final_label, final, b.rng.uniform(0.6, 1.0))


def _fall(b: _Builder) -> None:
    stumble = "stumbling_rollator" if b.locomotion is Locomotion.ROLLATOR else "stumbling"
    b.gait(stumble, b.rng.uniform(0.5, 1.0), amplitude=0.3, irregular=1.0)
    _fall_to_floor(b, "falling")
    _get_up(b, _upright(b), "standing")


def _fall_and_sit_up(b: _Builder) -> None:
    """A fall after which the patient sits on the floor before trying to get up."""
    _fall_to_floor(b, "falling")
    _get_up(b, _upright(b), "standing", sit_first=True)


def _stumble_and_recover(b: _Builder) -> None:
    stumble = "stumbling_rollator" if b.locomotion is Locomotion.ROLLATOR else "stumbling"
    b.gait(stumble, b.rng.uniform(0.6, 1.2), amplitude=0.3, irregular=1.0)
    b.move("standing", _upright(b), 0.6)


def _posture_of(params: np.ndarray, scale: float) -> dict[str, float]:
    out = {key: float(params[P[key]]) for key in PARAMS[2:]}
    out["pelvis_h"] /= scale
    return out


def _gesturing(b: _Builder) -> None:
    n = b.frames(b.rng.uniform(1.5, 3.0))
    base = np.repeat(b.last[None, :], n, axis=0)
    wave = np.sin(2 * np.pi * 1.5 * np.arange(n) / FPS)
    side = str(b.rng.choice(["r", "l"]))
    ramp = np.minimum(1.0, np.arange(n) / 10)
    base[:, P[f"sh_abd_{side}"]] += ramp * (1.4 + 0.4 * wave)
    base[:, P[f"elbow_{side}"]] += ramp * (0.8 + 0.4 * wave)
    b.add("gesturing", base)
    b.move("gesturing", _pose(b.last, b.scale, **_posture_of(base[0], b.scale)), 0.4)


def _turning(b: _Builder) -> None:
    home = b.last
    turned = home.copy()
    turned[P["yaw"]] += b.rng.choice([-1.0, 1.0]) * b.rng.uniform(1.2, 2.6)
    b.move("turning", turned, b.rng.uniform(1.0, 1.8))
    b.hold("turning", 0.5)
    b.move("turning", home, b.rng.uniform(1.0, 1.8))


def _too_far_away(b: _Builder) -> None:
    far = b.rng.uniform(4.8, 6.5)
    if b.locomotion is Locomotion.WHEELCHAIR:  # the wheelchair rolls away from the robot
        home = b.last
        away = home.copy()
        away[P["z"]] = far
        b.move("too_far_away", away, b.rng.uniform(2.0, 3.0))
        b.hold("too_far_away", b.rng.uniform(1.5, 3.0), jitter=0.02)
        b.move("sitting_wheelchair", home, b.rng.uniform(2.0, 3.0))
        return
    label = "walking_rollator" if b.locomotion is Locomotion.ROLLATOR else "walking"
    b.gait(label, 1.0, amplitude=0.2, arm_swing=0.1)
    b.gait("too_far_away", b.rng.uniform(2.0, 3.0), amplitude=0.15, arm_swing=0.1, z_target=far)
    b.gait("too_far_away", b.rng.uniform(1.5, 3.0), amplitude=0.1, arm_swing=0.05)
    b.gait(label, b.rng.uniform(2.0, 3.0), amplitude=0.3, z_target=b.follow_z)


def _lying_down_deliberately(b: _Builder) -> None:
    home = b.last
    sit = _pose(home, b.scale, pelvis_h=0.45, hip_flex_r=1.5, hip_flex_l=1.5, knee_r=1.5,
                knee_l=1.5, pitch=0.15, sh_flex_r=0.4, sh_flex_l=0.4)  # fmt: skip
    bed = b.rng.choice([0.15, 0.45])
    lie = _pose(home, b.scale, pelvis_h=float(bed), roll=1.45 * b.rng.choice([-1.0, 1.0]),
                hip_flex_r=0.3, hip_flex_l=0.2, knee_r=0.3, sh_flex_r=0.3)  # fmt: skip
    b.move("lying_down_deliberately", sit, b.rng.uniform(1.5, 2.2))
    b.move("lying_down_deliberately", lie, b.rng.uniform(2.0, 3.0))
    b.hold("lying_down_deliberately", b.rng.uniform(2.0, 4.0), jitter=0.005)
    b.move("sitting_down", sit, b.rng.uniform(1.5, 2.5))
    b.move("standing", _upright(b), b.rng.uniform(1.0, 1.5))


def _sitting_down(b: _Builder) -> None:
    chair = _pose(
        b.last,
        b.scale,
        pelvis_h=0.5,
        hip_flex_r=1.5,
        hip_flex_l=1.5,
        knee_r=1.5,
        knee_l=1.5,
        pitch=0.1,
        sh_flex_r=0.3,
        sh_flex_l=0.3,
        elbow_r=0.6,
        elbow_l=0.6,
    )
    mid = (b.last + chair) / 2
    mid[P["pitch"]] = 0.6
    b.move("sitting_down", mid, b.rng.uniform(0.7, 1.0))
    b.move("sitting_down", chair, b.rng.uniform(0.7, 1.0))
    b.hold("sitting_down", b.rng.uniform(1.0, 3.0), jitter=0.02)
    b.move("standing", mid, 0.8)
    b.move("standing", _upright(b), 0.8)


def _slump(b: _Builder) -> None:
    slumped = _pose(b.last, b.scale, **{**SIT_WHEELCHAIR, "pitch": 0.75,
                    "roll": 0.35 * b.rng.choice([-1.0, 1.0]), "head_pitch": 0.7, "sh_flex_r": 0.1,
                    "sh_flex_l": 0.05, "elbow_r": 0.1, "elbow_l": 0.15, "sh_abd_r": 0.1,
                    "sh_abd_l": 0.1, "pelvis_h": 0.5})  # fmt: skip
    b.move("slumped_unconscious_wheelchair", slumped, b.rng.uniform(1.0, 2.0))
    b.hold("slumped_unconscious_wheelchair", b.rng.uniform(3.0, 6.0), jitter=0.002)
    b.move("sitting_wheelchair", _pose(b.last, b.scale, **SIT_WHEELCHAIR), 1.5)


def _fall_out_of_wheelchair(b: _Builder) -> None:
    _fall_to_floor(b, "falling_out_of_wheelchair")
    _get_up(b, _pose(b.last, b.scale, **SIT_WHEELCHAIR), "sitting_wheelchair", sit_first=True)


def _stand_up_from_wheelchair(b: _Builder) -> None:
    lean = _pose(b.last, b.scale, **{**SIT_WHEELCHAIR, "pitch": 0.7, "pelvis_h": 0.6,
                 "sh_flex_r": 0.6, "sh_flex_l": 0.6, "elbow_r": 0.4, "elbow_l": 0.4})  # fmt: skip
    b.move("standing_up_from_wheelchair", lean, b.rng.uniform(0.6, 1.0))
    b.move("standing_up_from_wheelchair", _pose(b.last, b.scale), b.rng.uniform(0.8, 1.3))
    b.hold("standing_up_from_wheelchair", b.rng.uniform(1.0, 3.0), jitter=0.02)
    b.move("sitting_down", lean, b.rng.uniform(0.8, 1.2))
    b.move("sitting_wheelchair", _pose(b.last, b.scale, **SIT_WHEELCHAIR), 0.8)


def _crushing_hazard(b: _Builder) -> None:
    """An arm or a leg outside the wheelchair."""
    side = str(b.rng.choice(["r", "l"]))
    if b.rng.random() < 0.5:
        out = {f"sh_abd_{side}": b.rng.uniform(1.2, 1.6), f"elbow_{side}": 0.2,
               f"sh_flex_{side}": 0.2}  # fmt: skip
    else:
        out = {f"hip_abd_{side}": b.rng.uniform(0.6, 0.9), f"knee_{side}": 0.5}
    home = b.last
    b.move("crushing_hazard", _pose(home, b.scale, **{**SIT_WHEELCHAIR, **out}), 0.6)
    b.hold("crushing_hazard", b.rng.uniform(1.5, 3.0), jitter=0.01)
    b.move("sitting_wheelchair", home, 0.6)


def _bending(b: _Builder) -> None:
    if b.locomotion is Locomotion.WHEELCHAIR:
        target = _pose(b.last, b.scale, **{**SIT_WHEELCHAIR, "pitch": 0.9, "sh_flex_r": 0.9,
                       "elbow_r": 0.1, "roll": 0.3})  # fmt: skip
    else:
        target = _pose(b.last, b.scale, pelvis_h=0.9, pitch=1.2, hip_flex_r=0.1, hip_flex_l=0.1,
                       knee_r=0.2, knee_l=0.2, sh_flex_r=1.2, sh_flex_l=1.1)  # fmt: skip
    home = b.last
    b.move("bending", target, b.rng.uniform(0.8, 1.2))
    b.hold("bending", b.rng.uniform(0.8, 1.5), jitter=0.02)
    b.move("bending", home, b.rng.uniform(0.8, 1.2))


def _kneeling(b: _Builder) -> None:
    target = _pose(b.last, b.scale, pelvis_h=0.55, pitch=0.5, hip_flex_r=0.1, knee_r=1.7,
                   hip_flex_l=1.4, knee_l=1.4, sh_flex_r=1.0, sh_flex_l=1.0)  # fmt: skip
    home = b.last
    b.move("kneeling", target, b.rng.uniform(1.0, 1.5))
    b.hold("kneeling", b.rng.uniform(2.0, 4.0), jitter=0.02)
    b.move("kneeling", home, b.rng.uniform(1.0, 1.5))


def _standing(b: _Builder) -> None:
    b.move("standing", _upright(b), 0.5)
    b.hold("standing", b.rng.uniform(1.5, 3.0), jitter=0.015)


#: Events a transport can contain, by locomotion. Each event is named by the situation it
#: produces; composite events (a fall) walk through several fine labels.
EVENTS: dict[str, Callable[[_Builder], None]] = {
    "fall": _fall,
    "sitting_on_floor_after_fall": _fall_and_sit_up,
    "stumbling": _stumble_and_recover,
    "standing": _standing,
    "turning": _turning,
    "sitting_down": _sitting_down,
    "kneeling": _kneeling,
    "bending": _bending,
    "gesturing": _gesturing,
    "lying_down_deliberately": _lying_down_deliberately,
    "too_far_away": _too_far_away,
    "slumped_unconscious_wheelchair": _slump,
    "falling_out_of_wheelchair": _fall_out_of_wheelchair,
    "standing_up_from_wheelchair": _stand_up_from_wheelchair,
    "crushing_hazard": _crushing_hazard,
}
EVENTS_BY_LOCOMOTION: dict[Locomotion, tuple[str, ...]] = {
    Locomotion.WALKING: ("fall", "sitting_on_floor_after_fall", "stumbling", "standing",
                         "turning", "sitting_down", "kneeling", "bending", "gesturing",
                         "lying_down_deliberately", "too_far_away"),
    Locomotion.ROLLATOR: ("fall", "sitting_on_floor_after_fall", "stumbling", "standing",
                          "turning", "bending", "gesturing", "too_far_away"),
    Locomotion.WHEELCHAIR: ("slumped_unconscious_wheelchair", "falling_out_of_wheelchair",
                            "standing_up_from_wheelchair", "crushing_hazard", "gesturing",
                            "bending", "too_far_away"),
}  # fmt: skip
#: Events that make the ground truth Emergency at some point.
EMERGENCY_EVENTS: dict[Locomotion, tuple[str, ...]] = {
    Locomotion.WALKING: ("fall", "sitting_on_floor_after_fall", "stumbling"),
    Locomotion.ROLLATOR: ("fall", "sitting_on_floor_after_fall", "stumbling"),
    Locomotion.WHEELCHAIR: ("slumped_unconscious_wheelchair", "falling_out_of_wheelchair"),
}
_FALL_LABELS = ("falling", "impact", "lying_on_floor", "sitting_on_floor_after_fall",
                "trying_to_get_up")  # fmt: skip
#: The fine labels a transport of each locomotion can carry (all of them when every event of
#: EVENTS_BY_LOCOMOTION is generated); together they cover the whole DEFAULT_TAXONOMY.
LABELS_BY_LOCOMOTION: dict[Locomotion, frozenset[str]] = {
    Locomotion.WALKING: frozenset(("walking", "standing", "turning", "sitting_down", "kneeling",
                                   "bending", "gesturing", "lying_down_deliberately", "stumbling",
                                   "too_far_away", *_FALL_LABELS)),
    Locomotion.ROLLATOR: frozenset(("walking_rollator", "standing", "turning", "bending",
                                    "gesturing", "stumbling_rollator", "too_far_away",
                                    *_FALL_LABELS)),
    Locomotion.WHEELCHAIR: frozenset(("sitting_wheelchair", "sitting_down", "bending",
                                      "gesturing", "slumped_unconscious_wheelchair",
                                      "falling_out_of_wheelchair", "standing_up_from_wheelchair",
                                      "crushing_hazard", "too_far_away",
                                      *(k for k in _FALL_LABELS if k != "falling"))),
}  # fmt: skip


# --------------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------------


@dataclass
class GeneratedTransport:
    """A GENERATED transport.

    frames_per_person[p][t]: person p at frame t as a SkeletonFrame (BODY_25 pixels in a
    640x480 image, depth in metres), or None when the pose estimator would not see them.
    labels[t]: the patient's fine label at frame t. marker_px[t]: (u, v, side) in pixels of the
    ArUco marker on the patient's chest (NaN when not visible).
    """

    locomotion: Locomotion
    seed: int
    fps: float
    frames_per_person: list[list[SkeletonFrame | None]]
    patient_index: int
    labels: list[str]
    events: tuple[str, ...]
    marker_px: np.ndarray
    taxonomy: Taxonomy = DEFAULT_TAXONOMY
    generated: bool = True
    image_size: tuple[int, int] = (IMAGE_WIDTH, IMAGE_HEIGHT)

    @property
    def transport_mode(self) -> TransportMode:
        return self.locomotion.transport_mode

    @property
    def n_frames(self) -> int:
        return len(self.labels)

    @property
    def n_people(self) -> int:
        return len(self.frames_per_person)

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    @property
    def patient_frames(self) -> list[SkeletonFrame | None]:
        return self.frames_per_person[self.patient_index]

    def decisions(self, mode: TransportMode | None = None) -> list[Decision]:
        """Ground-truth class per frame (for ``mode``, default the transport's own)."""
        mode = mode or self.transport_mode
        cache = {key: self.taxonomy.decision(key, mode) for key in set(self.labels)}
        return [cache[key] for key in self.labels]

    def detections(self, t: int) -> list[SkeletonFrame]:
        """What a pose estimator reports at frame t: everyone visible, in no particular order
        (a deterministic shuffle), without identities."""
        return [self.frames_per_person[i][t] for i in self.detection_ids(t)]  # type: ignore[misc]

    def detection_ids(self, t: int) -> list[int]:
        """Ground truth for ``detections(t)``: the person index of each detection, same order."""
        seen = [i for i, p in enumerate(self.frames_per_person) if p[t] is not None]
        order = np.random.default_rng((self.seed, t)).permutation(len(seen))
        return [seen[i] for i in order]

    def patient_sequence(self, name: str | None = None) -> GeneratedSequence:
        """The patient alone as a ``GeneratedSequence``: frames where the patient is not
        seen have every keypoint missing (confidence 0) and NaN depth."""
        n = self.n_frames
        keypoints = np.zeros((n, N_KEYPOINTS, 3), np.float32)
        depth = np.full((n, N_KEYPOINTS), np.nan, np.float32)
        floor = np.full((n, N_FLOOR), np.nan, np.float32)
        for t, frame in enumerate(self.patient_frames):
            if frame is not None:
                keypoints[t], depth[t], floor[t] = frame.keypoints, frame.depth, frame.floor
        return GeneratedSequence(
            name or f"gen-{self.locomotion.value}-seed{self.seed}",
            keypoints,
            depth,
            np.arange(n) / self.fps,
            tuple(self.labels),
            floor=floor,
        )


# --------------------------------------------------------------------------------------------
# Rendering to keypoints with camera noise
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CameraNoise:
    pixel_sigma: float = 1.5  # at 2.5 m; grows with distance
    drop_probability: float = 0.03  # per keypoint and frame, more at the extremities
    depth_sigma_per_m2: float = 0.004  # Kinect: depth noise grows with the square of distance
    depth_dropout: float = 0.03


_EXTREMITY_NAMES = ("r_wrist", "l_wrist", "l_big_toe", "l_small_toe", "l_heel", "r_big_toe",
                    "r_small_toe", "r_heel", "r_ear", "l_ear")  # fmt: skip
_EXTREMITIES = np.array([INDEX[k] for k in _EXTREMITY_NAMES])


def _render(
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
    measured = np.where(missing | (rng.random(depth.shape) < noise.depth_dropout), np.nan,
                        measured)  # fmt: skip
    return keypoints, measured.astype(np.float32)


def _occlude(front: np.ndarray, front_depth: np.ndarray, back: np.ndarray,
             back_depth: np.ndarray) -> None:  # fmt: skip
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


def _bystander_params(rng: np.random.Generator, n: int, scale: float, patient_z: float,
                      ) -> np.ndarray:  # fmt: skip
    """Someone crossing the view once, in front of or behind the patient."""
    speed = rng.uniform(0.8, 1.4) * rng.choice([-1.0, 1.0])
    crossing_time = rng.uniform(0.15, 0.85) * n / FPS
    z = float(np.clip(patient_z + rng.choice([-1.0, 1.0]) * rng.uniform(0.6, 1.8), 1.3, 6.0))
    t = np.arange(n) / FPS
    params = np.zeros((n, len(PARAMS)))
    base = _pose(np.zeros(len(PARAMS)), scale)
    params[:] = base
    params[:, P["x"]] = speed * (t - crossing_time)
    params[:, P["z"]] = z
    params[:, P["yaw"]] = math.copysign(math.pi / 2, speed)
    phase = 2 * np.pi * rng.uniform(0.8, 1.0) * t + rng.uniform(0, 6.3)
    swing = np.sin(phase)
    params[:, P["hip_flex_r"]] += 0.35 * swing
    params[:, P["hip_flex_l"]] -= 0.35 * swing
    params[:, P["knee_r"]] += 0.55 * np.clip(-np.cos(phase), 0, None)
    params[:, P["knee_l"]] += 0.55 * np.clip(np.cos(phase), 0, None)
    params[:, P["sh_flex_r"]] -= 0.3 * swing
    params[:, P["sh_flex_l"]] += 0.3 * swing
    return params


def generate_transport(
    mode: Locomotion | str = Locomotion.WALKING,
    seed: int = 0,
    duration_s: float = 30.0,
    events: Sequence[str] | None = None,
    n_people: int = 1,
    noise: CameraNoise | None = None,
) -> GeneratedTransport:
    """Generate one transport (GENERATED data).

    mode: walking, rollator or wheelchair. events: names from ``EVENTS_BY_LOCOMOTION[mode]``
    in order (None: one to three picked by the seed, at least one an emergency). n_people: 1-5
    people in view, the patient plus crossing bystanders. The transport lasts at least
    ``duration_s`` (longer when the events need it), normal activity filling the gaps.
    """
    locomotion = Locomotion(mode)
    if not 1 <= n_people <= 5:
        raise ValueError(f"n_people must be 1-5, got {n_people}")
    if duration_s <= 0:
        raise ValueError(f"duration_s must be positive, got {duration_s}")
    allowed = EVENTS_BY_LOCOMOTION[locomotion]
    rng = np.random.default_rng(seed)
    if events is None:
        count = int(rng.integers(1, 4))
        chosen = [str(rng.choice(EMERGENCY_EVENTS[locomotion]))]
        chosen += [str(rng.choice(allowed)) for _ in range(count - 1)]
        rng.shuffle(chosen)
        events = chosen
    for event in events:
        if event not in allowed:
            raise ValueError(
                f"event {event!r} is not possible when {locomotion.value}; choose from {allowed}"
            )
    noise = noise or CameraNoise()
    scale = rng.uniform(0.88, 1.08)
    seated = locomotion is Locomotion.WHEELCHAIR
    follow_z = rng.uniform(1.9, 2.3) if seated else rng.uniform(2.6, 3.1)
    b = _Builder(rng=rng, scale=scale, locomotion=locomotion, follow_z=follow_z)
    start = np.zeros(len(PARAMS))
    start[P["x"]] = rng.uniform(-0.15, 0.15)
    start[P["z"]] = follow_z
    start = _pose(start, scale, **(SIT_WHEELCHAIR if seated else {}))
    b.segments.append(("sitting_wheelchair" if seated else "standing", start[None, :]))
    b.segments[0] = (b.segments[0][0], _upright(b)[None, :] if not seated else start[None, :])
    budget = max(duration_s - 4.0 * (len(events) + 1), 0.0)
    gaps = rng.dirichlet(np.ones(len(events) + 1)) * budget + 2.0
    _base(b, gaps[0])
    for event, gap in zip(events, gaps[1:], strict=True):
        EVENTS[event](b)
        _base(b, gap)
    labels = [label for label, seg in b.segments for _ in range(len(seg))]
    params = np.concatenate([seg for _, seg in b.segments])
    need = round(duration_s * FPS)
    if len(labels) < need:
        _base(b, (need - len(labels)) / FPS + 1 / FPS)
        labels = [label for label, seg in b.segments for _ in range(len(seg))]
        params = np.concatenate([seg for _, seg in b.segments])
    n = len(labels)

    world = [body_points(params, scale)]
    for _ in range(n_people - 1):
        other_scale = rng.uniform(0.9, 1.1)
        world.append(body_points(_bystander_params(rng, n, other_scale, follow_z), other_scale))
    rendered = [_render(w, rng, noise) for w in world]
    for i in range(len(rendered)):
        for j in range(len(rendered)):
            if i != j:
                _occlude(rendered[j][0], rendered[j][1], rendered[i][0], rendered[i][1])

    order = rng.permutation(n_people)  # the patient is not always person 0
    people: list[list[SkeletonFrame | None]] = []
    for idx in order:
        keypoints, depth = rendered[idx]
        visible = (keypoints[:, :, 2] > 0).sum(-1) >= MIN_VISIBLE_KEYPOINTS
        floor = floor_measures_many(keypoints, depth, CAMERA_MOUNT)
        people.append([
            SkeletonFrame(keypoints[t], depth[t], timestamp=t / FPS, floor=floor[t])
            if visible[t] else None
            for t in range(n)
        ])  # fmt: skip
    patient_index = int(np.flatnonzero(order == 0)[0])

    chest_world = world[0][:, INDEX["neck"]] * 0.7 + world[0][:, INDEX["mid_hip"]] * 0.3
    chest_px, chest_depth = project(chest_world)
    side = FOCAL_PX * MARKER_SIZE_M / np.where(chest_depth > 0.3, chest_depth, np.nan)
    marker = np.concatenate([chest_px, side[:, None]], axis=-1)
    patient_seen = np.array([f is not None for f in people[patient_index]])
    marker[~patient_seen] = np.nan
    return GeneratedTransport(
        locomotion=locomotion,
        seed=seed,
        fps=FPS,
        frames_per_person=people,
        patient_index=patient_index,
        labels=labels,
        events=tuple(events),
        marker_px=marker.astype(np.float32),
    )
