"""What a model needs in each frame, and what a robot can feed it.

Every model needs keypoints. A model whose features use the floor measures (vigil.floor: the
height of the person's top and centre above the floor, the share near it) needs ``floor``; a
model fitted on frames with depth at the keypoints needs ``depth``. A robot can feed ``depth``
when its source has a depth image (or a recording with depth), and ``floor`` when it also knows
the camera's mount over the floor (or its recording carries floor measures).

A model runs on a robot only when the robot feeds every input it needs (the backend refuses the
assignment otherwise, 409); a robot that loses an input during a transport switches to its
keypoints-only fallback model and raises "detection degraded".
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal

InputName = Literal["keypoints", "depth", "floor"]
KEYPOINTS: InputName = "keypoints"
DEPTH: InputName = "depth"
FLOOR: InputName = "floor"
ALL_INPUTS: tuple[InputName, ...] = (KEYPOINTS, DEPTH, FLOOR)
#: Feature sets (vigil.features.FEATURE_SETS) whose columns include the floor measures.
FLOOR_FEATURE_SETS = frozenset({"full"})


def model_inputs(feature_set: str, fitted_with_depth: bool = False) -> list[InputName]:
    """The inputs a model of ``feature_set`` needs, in ALL_INPUTS order."""
    needed = {KEYPOINTS}
    if fitted_with_depth:
        needed.add(DEPTH)
    if feature_set in FLOOR_FEATURE_SETS:
        needed.add(FLOOR)
    return [name for name in ALL_INPUTS if name in needed]


def normalise(inputs: Iterable[str]) -> list[InputName]:
    """Known input names in ALL_INPUTS order (keypoints always); raises on an unknown name."""
    given = set(inputs)
    unknown = given - set(ALL_INPUTS)
    if unknown:
        raise ValueError(f"unknown inputs {sorted(unknown)}; known: {list(ALL_INPUTS)}")
    return [name for name in ALL_INPUTS if name in given or name == KEYPOINTS]


def missing_inputs(needed: Iterable[str], available: Iterable[str] | None) -> list[InputName]:
    """The inputs in ``needed`` that ``available`` lacks (None: only keypoints are known)."""
    have = set(available) if available is not None else {KEYPOINTS}
    return [name for name in ALL_INPUTS if name in set(needed) and name not in have]


def is_keypoints_only(inputs: Iterable[str]) -> bool:
    return set(inputs) <= {KEYPOINTS}


def describe_missing(model: str, missing: Iterable[str], robot: str | None = None) -> str:
    """A sentence for 409s and alarms: "robot robot-1 cannot feed model gbt-...: it has no floor
    measures"."""
    words = {KEYPOINTS: "keypoints", DEPTH: "depth at the keypoints", FLOOR: "floor measures"}
    what = " and ".join(words[m] for m in missing)
    who = f"robot {robot}" if robot else "this robot"
    return f"{who} cannot feed model {model}: it has no {what}"
