"""Which robots can feed which model, and each mode's keypoints-only fallback.

A model needs the inputs its stored manifest names (``ModelManifest.inputs``; manifests stored
before the field existed: derived from their feature set). A robot feeds what it said in its last
hello (``Robot.inputs``; nothing said = keypoints only). A model is assigned only to robots that
feed every input it needs: the rollout services refuse the rest (HTTP 409).

The fallback of a mode is its most recent *production* model (promoted, not retired) whose
manifest needs keypoints only. A robot whose assigned model needs more keeps that fallback beside
it (``assign_model`` with ``fallback: true``) and switches to it when an input goes missing.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models.registry import ModelStatus, ModelVersion
from backend.models.robots import Robot
from vigil.classes import TransportMode
from vigil.inputs import InputName, describe_missing, is_keypoints_only, model_inputs, normalise

#: How many robots a refusal names before it says "and N more".
NAMED_IN_REFUSAL = 5


def model_needs(model: ModelVersion) -> list[InputName]:
    manifest = model.manifest or {}
    if manifest.get("inputs"):
        return normalise(manifest["inputs"])
    return model_inputs(manifest.get("feature_set", "full"))


def missing_for(robot: Robot, model: ModelVersion) -> list[InputName]:
    have = set(robot.feeds)
    return [name for name in model_needs(model) if name not in have]


def is_fallback_candidate(model: ModelVersion) -> bool:
    return is_keypoints_only(model_needs(model))


@dataclass(frozen=True)
class Qualification:
    robot_id: str
    qualifies: bool
    missing: list[InputName]
    reason: str | None


def qualify(robots: Iterable[Robot], model: ModelVersion) -> list[Qualification]:
    out = []
    for robot in robots:
        missing = missing_for(robot, model)
        reason = describe_missing(model.version, missing, robot.id) if missing else None
        out.append(Qualification(robot.id, not missing, missing, reason))
    return out


def refusal(model: ModelVersion, refused: list[Qualification], in_scope: int) -> str:
    """The 409 detail: the robots that cannot feed the model, each with what it lacks."""
    named = "; ".join(q.reason for q in refused[:NAMED_IN_REFUSAL])
    if len(refused) > NAMED_IN_REFUSAL:
        named += f"; and {len(refused) - NAMED_IN_REFUSAL} more"
    if in_scope == 1:
        return named
    return (
        f"{len(refused)} of {in_scope} robots in the scope cannot feed model {model.version}: "
        f"{named}. Narrow the scope to robots that can, or promote with only_capable"
    )


def fallback_model(
    session: Session, mode: TransportMode | str, exclude: int | None = None
) -> ModelVersion | None:
    """The mode's fallback: its most recent production model that needs keypoints only."""
    query = (
        select(ModelVersion)
        .where(ModelVersion.mode == mode, ModelVersion.status == ModelStatus.PRODUCTION)
        .order_by(ModelVersion.created_at.desc(), ModelVersion.id.desc())
    )
    for model in session.scalars(query):
        if model.id != exclude and is_fallback_candidate(model):
            return model
    return None


def fallback_for(
    session: Session, assigned: ModelVersion | None, cache: dict | None = None
) -> ModelVersion | None:
    """The fallback a robot assigned `assigned` keeps beside it (None: it needs none)."""
    if assigned is None or is_fallback_candidate(assigned):
        return None
    if cache is None:
        return fallback_model(session, assigned.mode)
    if assigned.mode not in cache:
        cache[assigned.mode] = fallback_model(session, assigned.mode)
    return cache[assigned.mode]
