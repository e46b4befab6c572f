"""A small kinematic body: pelvis position, trunk yaw/pitch/roll, hip, knee, shoulder and elbow
angles (a parameter vector per frame) and the BODY_25 world points they put the body at."""

from __future__ import annotations

import numpy as np

from vigil.skeleton import INDEX, N_KEYPOINTS

PARAMS: tuple[str, ...] = (
    "x",
    "z",
    "pelvis_h",
    "yaw",
    "pitch",
    "roll",
    "head_pitch",
    "hip_flex_r",
    "hip_flex_l",
    "knee_r",
    "knee_l",
    "hip_abd_r",
    "hip_abd_l",
    "sh_flex_r",
    "sh_flex_l",
    "sh_abd_r",
    "sh_abd_l",
    "elbow_r",
    "elbow_l",
)
P = {name: i for i, name in enumerate(PARAMS)}

STAND: dict[str, float] = {
    "pelvis_h": 0.95,
    "sh_abd_r": 0.08,
    "sh_abd_l": 0.08,
    "elbow_r": 0.1,
    "elbow_l": 0.1,
}
SIT_WHEELCHAIR: dict[str, float] = {
    "pelvis_h": 0.52,
    "hip_flex_r": 1.5,
    "hip_flex_l": 1.5,
    "knee_r": 1.45,
    "knee_l": 1.45,
    "sh_flex_r": 0.35,
    "sh_flex_l": 0.35,
    "sh_abd_r": 0.25,
    "sh_abd_l": 0.25,
    "elbow_r": 1.2,
    "elbow_l": 1.2,
    "pitch": 0.05,
}


def pose(base: np.ndarray, scale: float, **overrides: float) -> np.ndarray:
    """A parameter vector: ``base`` with the body-posture entries replaced (heights scaled)."""
    out = base.copy()
    for key in PARAMS[2:]:
        out[P[key]] = 0.0
    for key, value in {**STAND, **overrides}.items():
        out[P[key]] = value * scale if key == "pelvis_h" else value
    return out


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
