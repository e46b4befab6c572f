"""Activities: how the patient moves during a transport (Locomotion) and the events a transport
can contain, each appending (fine label, body parameters) segments that continue from the last
pose."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from vigil.classes import TransportMode
from vigil.synthetic.camera import FPS
from vigil.synthetic.kinematics import PARAMS, SIT_WHEELCHAIR, P, pose


class Locomotion(StrEnum):
    """How the patient moves during the transport (the generator's 'mode')."""

    WALKING = "walking"
    ROLLATOR = "rollator"
    WHEELCHAIR = "wheelchair"

    @property
    def transport_mode(self) -> TransportMode:
        return TransportMode.WHEELCHAIR if self is Locomotion.WHEELCHAIR else TransportMode.WALKING


def _smooth(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return s * s * (3 - 2 * s)


def _accelerating(n: int) -> np.ndarray:
    return np.linspace(0.0, 1.0, n) ** 2  # gravity: slow start, fast end


@dataclass
class Builder:
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


def upright(b: Builder) -> np.ndarray:
    if b.locomotion is Locomotion.ROLLATOR:
        return pose(
            b.last,
            b.scale,
            pitch=0.25,
            sh_flex_r=0.75,
            sh_flex_l=0.75,
            elbow_r=0.7,
            elbow_l=0.7,
            sh_abd_r=0.1,
            sh_abd_l=0.1,
        )
    return pose(b.last, b.scale)


def base_activity(b: Builder, seconds: float) -> None:
    """The normal state of the transport: walking (with or without rollator) or sitting."""
    if b.locomotion is Locomotion.WHEELCHAIR:
        b.hold("sitting_wheelchair", seconds, jitter=0.02)
        return
    label = "walking_rollator" if b.locomotion is Locomotion.ROLLATOR else "walking"
    amplitude = 0.22 if b.locomotion is Locomotion.ROLLATOR else 0.35
    b.gait(
        label,
        seconds,
        amplitude=amplitude,
        arm_swing=0.05 if b.locomotion is Locomotion.ROLLATOR else 0.3,
        z_target=b.follow_z + b.rng.uniform(-0.15, 0.15),
    )


def _lying_pose(b: Builder) -> np.ndarray:
    direction = b.rng.choice(["side", "side", "forward", "backward"])
    sign = b.rng.choice([-1.0, 1.0])
    roll = sign * b.rng.uniform(1.3, 1.5) if direction == "side" else sign * 0.2
    pitch = {"side": 0.1, "forward": 1.45, "backward": -1.45}[str(direction)]
    return pose(
        b.last,
        b.scale,
        pelvis_h=0.12,
        roll=roll,
        pitch=pitch,
        sh_abd_r=1.1,
        sh_abd_l=0.9,
        hip_flex_r=0.3,
        knee_r=0.4,
        elbow_r=0.4,
        elbow_l=0.6,
    )


def _fall_to_floor(b: Builder, first_label: str) -> None:
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


def _get_up(b: Builder, final: np.ndarray, final_label: str, sit_first: bool | None = None) -> None:
    if sit_first is None:
        sit_first = bool(b.rng.random() < 0.6)
    if sit_first:
        sit = pose(
            b.last,
            b.scale,
            pelvis_h=0.12,
            hip_flex_r=1.45,
            hip_flex_l=1.45,
            knee_r=0.5,
            knee_l=0.3,
            pitch=0.2,
            sh_flex_r=0.5,
            sh_flex_l=0.4,
        )
        b.move("sitting_on_floor_after_fall", sit, b.rng.uniform(1.0, 1.8))
        b.hold("sitting_on_floor_after_fall", b.rng.uniform(1.0, 2.5), jitter=0.02)
    kneel = pose(
        b.last,
        b.scale,
        pelvis_h=0.45,
        pitch=1.2,
        hip_flex_r=1.4,
        hip_flex_l=1.4,
        knee_r=1.9,
        knee_l=1.9,
        sh_flex_r=1.3,
        sh_flex_l=1.3,
    )
    for _ in range(int(b.rng.integers(1, 3))):  # failed attempts
        b.move("trying_to_get_up", kneel, b.rng.uniform(0.8, 1.3))
        down = pose(
            b.last,
            b.scale,
            pelvis_h=0.2,
            pitch=1.3,
            hip_flex_r=1.2,
            hip_flex_l=1.2,
            knee_r=1.7,
            knee_l=1.7,
            sh_flex_r=1.4,
            sh_flex_l=1.4,
        )
        b.move("trying_to_get_up", down, b.rng.uniform(0.5, 0.9))
    b.move("trying_to_get_up", kneel, b.rng.uniform(0.8, 1.2))
    half = (b.last + final) / 2
    b.move("trying_to_get_up", half, b.rng.uniform(0.8, 1.2))
    b.move(final_label, final, b.rng.uniform(0.6, 1.0))


def _fall(b: Builder) -> None:
    stumble = "stumbling_rollator" if b.locomotion is Locomotion.ROLLATOR else "stumbling"
    b.gait(stumble, b.rng.uniform(0.5, 1.0), amplitude=0.3, irregular=1.0)
    _fall_to_floor(b, "falling")
    _get_up(b, upright(b), "standing")


def _fall_and_sit_up(b: Builder) -> None:
    """A fall after which the patient sits on the floor before trying to get up."""
    _fall_to_floor(b, "falling")
    _get_up(b, upright(b), "standing", sit_first=True)


def _stumble_and_recover(b: Builder) -> None:
    stumble = "stumbling_rollator" if b.locomotion is Locomotion.ROLLATOR else "stumbling"
    b.gait(stumble, b.rng.uniform(0.6, 1.2), amplitude=0.3, irregular=1.0)
    b.move("standing", upright(b), 0.6)


def _posture_of(params: np.ndarray, scale: float) -> dict[str, float]:
    out = {key: float(params[P[key]]) for key in PARAMS[2:]}
    out["pelvis_h"] /= scale
    return out


def _gesturing(b: Builder) -> None:
    n = b.frames(b.rng.uniform(1.5, 3.0))
    base = np.repeat(b.last[None, :], n, axis=0)
    wave = np.sin(2 * np.pi * 1.5 * np.arange(n) / FPS)
    side = str(b.rng.choice(["r", "l"]))
    ramp = np.minimum(1.0, np.arange(n) / 10)
    base[:, P[f"sh_abd_{side}"]] += ramp * (1.4 + 0.4 * wave)
    base[:, P[f"elbow_{side}"]] += ramp * (0.8 + 0.4 * wave)
    b.add("gesturing", base)
    b.move("gesturing", pose(b.last, b.scale, **_posture_of(base[0], b.scale)), 0.4)


def _turning(b: Builder) -> None:
    home = b.last
    turned = home.copy()
    turned[P["yaw"]] += b.rng.choice([-1.0, 1.0]) * b.rng.uniform(1.2, 2.6)
    b.move("turning", turned, b.rng.uniform(1.0, 1.8))
    b.hold("turning", 0.5)
    b.move("turning", home, b.rng.uniform(1.0, 1.8))


def _too_far_away(b: Builder) -> None:
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


def _lying_down_deliberately(b: Builder) -> None:
    home = b.last
    sit = pose(
        home,
        b.scale,
        pelvis_h=0.45,
        hip_flex_r=1.5,
        hip_flex_l=1.5,
        knee_r=1.5,
        knee_l=1.5,
        pitch=0.15,
        sh_flex_r=0.4,
        sh_flex_l=0.4,
    )
    # On a bed or couch: a hospital bed's mattress is 0.45-0.8 m above the floor, so the pelvis
    # rests 0.55-0.8 m up (absolute, not scaled with the body). Lying lower than that is lying on
    # the floor, which looks like (and is labelled as) the end of a fall.
    bed = b.rng.uniform(0.55, 0.8) / b.scale
    lie = pose(
        home,
        b.scale,
        pelvis_h=float(bed),
        roll=1.45 * b.rng.choice([-1.0, 1.0]),
        hip_flex_r=0.3,
        hip_flex_l=0.2,
        knee_r=0.3,
        sh_flex_r=0.3,
    )
    b.move("lying_down_deliberately", sit, b.rng.uniform(1.5, 2.2))
    b.move("lying_down_deliberately", lie, b.rng.uniform(2.0, 3.0))
    b.hold("lying_down_deliberately", b.rng.uniform(2.0, 4.0), jitter=0.005)
    b.move("sitting_down", sit, b.rng.uniform(1.5, 2.5))
    b.move("standing", upright(b), b.rng.uniform(1.0, 1.5))


def _sitting_down(b: Builder) -> None:
    chair = pose(
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
    b.move("standing", upright(b), 0.8)


def _slump(b: Builder) -> None:
    slumped = pose(
        b.last,
        b.scale,
        **{
            **SIT_WHEELCHAIR,
            "pitch": 0.75,
            "roll": 0.35 * b.rng.choice([-1.0, 1.0]),
            "head_pitch": 0.7,
            "sh_flex_r": 0.1,
            "sh_flex_l": 0.05,
            "elbow_r": 0.1,
            "elbow_l": 0.15,
            "sh_abd_r": 0.1,
            "sh_abd_l": 0.1,
            "pelvis_h": 0.5,
        },
    )
    b.move("slumped_unconscious_wheelchair", slumped, b.rng.uniform(1.0, 2.0))
    b.hold("slumped_unconscious_wheelchair", b.rng.uniform(3.0, 6.0), jitter=0.002)
    b.move("sitting_wheelchair", pose(b.last, b.scale, **SIT_WHEELCHAIR), 1.5)


def _fall_out_of_wheelchair(b: Builder) -> None:
    _fall_to_floor(b, "falling_out_of_wheelchair")
    _get_up(b, pose(b.last, b.scale, **SIT_WHEELCHAIR), "sitting_wheelchair", sit_first=True)


def _stand_up_from_wheelchair(b: Builder) -> None:
    lean = pose(
        b.last,
        b.scale,
        **{
            **SIT_WHEELCHAIR,
            "pitch": 0.7,
            "pelvis_h": 0.6,
            "sh_flex_r": 0.6,
            "sh_flex_l": 0.6,
            "elbow_r": 0.4,
            "elbow_l": 0.4,
        },
    )
    b.move("standing_up_from_wheelchair", lean, b.rng.uniform(0.6, 1.0))
    b.move("standing_up_from_wheelchair", pose(b.last, b.scale), b.rng.uniform(0.8, 1.3))
    b.hold("standing_up_from_wheelchair", b.rng.uniform(1.0, 3.0), jitter=0.02)
    b.move("sitting_down", lean, b.rng.uniform(0.8, 1.2))
    b.move("sitting_wheelchair", pose(b.last, b.scale, **SIT_WHEELCHAIR), 0.8)


def _crushing_hazard(b: Builder) -> None:
    """An arm or a leg outside the wheelchair."""
    side = str(b.rng.choice(["r", "l"]))
    if b.rng.random() < 0.5:
        out = {
            f"sh_abd_{side}": b.rng.uniform(1.2, 1.6),
            f"elbow_{side}": 0.2,
            f"sh_flex_{side}": 0.2,
        }
    else:
        out = {f"hip_abd_{side}": b.rng.uniform(0.6, 0.9), f"knee_{side}": 0.5}
    home = b.last
    b.move("crushing_hazard", pose(home, b.scale, **{**SIT_WHEELCHAIR, **out}), 0.6)
    b.hold("crushing_hazard", b.rng.uniform(1.5, 3.0), jitter=0.01)
    b.move("sitting_wheelchair", home, 0.6)


def _bending(b: Builder) -> None:
    if b.locomotion is Locomotion.WHEELCHAIR:
        target = pose(
            b.last,
            b.scale,
            **{**SIT_WHEELCHAIR, "pitch": 0.9, "sh_flex_r": 0.9, "elbow_r": 0.1, "roll": 0.3},
        )
    else:
        target = pose(
            b.last,
            b.scale,
            pelvis_h=0.9,
            pitch=1.2,
            hip_flex_r=0.1,
            hip_flex_l=0.1,
            knee_r=0.2,
            knee_l=0.2,
            sh_flex_r=1.2,
            sh_flex_l=1.1,
        )
    home = b.last
    b.move("bending", target, b.rng.uniform(0.8, 1.2))
    b.hold("bending", b.rng.uniform(0.8, 1.5), jitter=0.02)
    b.move("bending", home, b.rng.uniform(0.8, 1.2))


def _kneeling(b: Builder) -> None:
    target = pose(
        b.last,
        b.scale,
        pelvis_h=0.55,
        pitch=0.5,
        hip_flex_r=0.1,
        knee_r=1.7,
        hip_flex_l=1.4,
        knee_l=1.4,
        sh_flex_r=1.0,
        sh_flex_l=1.0,
    )
    home = b.last
    b.move("kneeling", target, b.rng.uniform(1.0, 1.5))
    b.hold("kneeling", b.rng.uniform(2.0, 4.0), jitter=0.02)
    b.move("kneeling", home, b.rng.uniform(1.0, 1.5))


def _standing(b: Builder) -> None:
    b.move("standing", upright(b), 0.5)
    b.hold("standing", b.rng.uniform(1.5, 3.0), jitter=0.015)


#: Events a transport can contain, by locomotion. Each event is named by the situation it
#: produces; composite events (a fall) walk through several fine labels.
EVENTS: dict[str, Callable[[Builder], None]] = {
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
    Locomotion.WALKING: (
        "fall",
        "sitting_on_floor_after_fall",
        "stumbling",
        "standing",
        "turning",
        "sitting_down",
        "kneeling",
        "bending",
        "gesturing",
        "lying_down_deliberately",
        "too_far_away",
    ),
    Locomotion.ROLLATOR: (
        "fall",
        "sitting_on_floor_after_fall",
        "stumbling",
        "standing",
        "turning",
        "bending",
        "gesturing",
        "too_far_away",
    ),
    Locomotion.WHEELCHAIR: (
        "slumped_unconscious_wheelchair",
        "falling_out_of_wheelchair",
        "standing_up_from_wheelchair",
        "crushing_hazard",
        "gesturing",
        "bending",
        "too_far_away",
    ),
}
#: Events that make the ground truth Emergency at some point.
EMERGENCY_EVENTS: dict[Locomotion, tuple[str, ...]] = {
    Locomotion.WALKING: ("fall", "sitting_on_floor_after_fall", "stumbling"),
    Locomotion.ROLLATOR: ("fall", "sitting_on_floor_after_fall", "stumbling"),
    Locomotion.WHEELCHAIR: ("slumped_unconscious_wheelchair", "falling_out_of_wheelchair"),
}
_FALL_LABELS = (
    "falling",
    "impact",
    "lying_on_floor",
    "sitting_on_floor_after_fall",
    "trying_to_get_up",
)
#: The fine labels a transport of each locomotion can carry (all of them when every event of
#: EVENTS_BY_LOCOMOTION is generated); together they cover the whole DEFAULT_TAXONOMY.
LABELS_BY_LOCOMOTION: dict[Locomotion, frozenset[str]] = {
    Locomotion.WALKING: frozenset(
        (
            "walking",
            "standing",
            "turning",
            "sitting_down",
            "kneeling",
            "bending",
            "gesturing",
            "lying_down_deliberately",
            "stumbling",
            "too_far_away",
            *_FALL_LABELS,
        )
    ),
    Locomotion.ROLLATOR: frozenset(
        (
            "walking_rollator",
            "standing",
            "turning",
            "bending",
            "gesturing",
            "stumbling_rollator",
            "too_far_away",
            *_FALL_LABELS,
        )
    ),
    Locomotion.WHEELCHAIR: frozenset(
        (
            "sitting_wheelchair",
            "sitting_down",
            "bending",
            "gesturing",
            "slumped_unconscious_wheelchair",
            "falling_out_of_wheelchair",
            "standing_up_from_wheelchair",
            "crushing_hazard",
            "too_far_away",
            *(k for k in _FALL_LABELS if k != "falling"),
        )
    ),
}
