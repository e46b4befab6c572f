"""OpenPose JSON (as `openpose --write_json` writes it) -> SkeletonFrame."""

from __future__ import annotations

from typing import Any

import numpy as np

from vigil.skeleton import N_KEYPOINTS, SkeletonFrame


def from_openpose_json(document: dict[str, Any], timestamp: float = 0.0) -> list[SkeletonFrame]:
    """One SkeletonFrame per entry of `people[]`, from its `pose_keypoints_2d` (75 numbers)."""
    people = document.get("people")
    if not isinstance(people, list):
        raise ValueError("openpose json: 'people' must be a list")
    frames = []
    for i, person in enumerate(people):
        flat = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
        if flat is None or len(flat) != N_KEYPOINTS * 3:
            raise ValueError(
                f"openpose json: people[{i}].pose_keypoints_2d must hold {N_KEYPOINTS * 3} numbers"
            )
        keypoints = np.asarray(flat, dtype=np.float32).reshape(N_KEYPOINTS, 3)
        if not np.isfinite(keypoints).all():
            raise ValueError(f"openpose json: people[{i}].pose_keypoints_2d has a non-finite value")
        keypoints[keypoints[:, 2] <= 0] = 0.0
        frames.append(SkeletonFrame(keypoints=keypoints, timestamp=timestamp))
    return frames
