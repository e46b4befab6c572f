"""People other than the patient crossing the camera's view."""

from __future__ import annotations

import math

import numpy as np

from vigil.synthetic.camera import FPS
from vigil.synthetic.kinematics import PARAMS, P, pose


def bystander_params(
    rng: np.random.Generator,
    n: int,
    scale: float,
    patient_z: float,
) -> np.ndarray:
    """Someone crossing the view once, in front of or behind the patient."""
    speed = rng.uniform(0.8, 1.4) * rng.choice([-1.0, 1.0])
    crossing_time = rng.uniform(0.15, 0.85) * n / FPS
    z = float(np.clip(patient_z + rng.choice([-1.0, 1.0]) * rng.uniform(0.6, 1.8), 1.3, 6.0))
    t = np.arange(n) / FPS
    params = np.zeros((n, len(PARAMS)))
    base = pose(np.zeros(len(PARAMS)), scale)
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
