"""Promotion, staged rollout, rollback and shadow deployments: which model each robot should run.

A deployment names a model and a scope (one robot, a ward, the fleet). A promotion that passed
the gate starts with one canary robot (a scope of several robots) and reaches the rest on
`advance`, once the canary reports that it runs the new version. Every robot's previous
assignment is kept in the deployment, so a rollback restores exactly what each robot had.
A model reaches only robots that feed every input it needs (backend.registry.capability): a
scope holding a robot that cannot is refused (409) unless the promotion asks for
`only_capable`, which leaves those robots out (listed in `rollout["skipped"]`). A rollback that
would retire a mode's last keypoints-only production model (every robot's fallback) is refused.
Services change the session; the request (or the job) commits.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models._types import utcnow
from backend.models.registry import (
    Deployment,
    DeploymentScope,
    DeploymentStatus,
    ModelStatus,
    ModelVersion,
)
from backend.models.robots import Robot
from backend.models.users import User
from backend.registry import capability
from vigil.states import IllegalTransition, StateMachine

LIVE = (DeploymentStatus.CANARY, DeploymentStatus.ACTIVE)


class RolloutError(ValueError):
    """A request that conflicts with the current state (HTTP 409)."""


class CapabilityError(RolloutError):
    """A robot in the scope cannot feed the model an input it needs (HTTP 409)."""


class RolloutStateError(IllegalTransition, RolloutError):
    """A deployment or model version status change its table does not allow (HTTP 409)."""


ROLLOUT = StateMachine(
    DeploymentStatus,
    edges={
        DeploymentStatus.PENDING_APPROVAL: {
            DeploymentStatus.CANARY,
            DeploymentStatus.ACTIVE,
            DeploymentStatus.ROLLED_BACK,
        },
        DeploymentStatus.CANARY: {
            DeploymentStatus.ACTIVE,
            DeploymentStatus.ROLLED_BACK,
            DeploymentStatus.SUPERSEDED,
        },
        DeploymentStatus.ACTIVE: {DeploymentStatus.ROLLED_BACK, DeploymentStatus.SUPERSEDED},
        DeploymentStatus.ROLLED_BACK: set(),
        DeploymentStatus.SUPERSEDED: set(),
    },
    initial=DeploymentStatus.PENDING_APPROVAL,
    subject=lambda deployment: f"deployment {deployment.id}",
    error=RolloutStateError,
)
_C, _A, _P, _R = ModelStatus  # candidate, approved, production, retired
#: The moves `_start`, `advance` and `rollback` make, and only those. A registered model is a
#: candidate (`worker.registration`) and never becomes one again. A canary start approves a
#: candidate or a retired model; a model already approved or in production keeps its status
#: (in production it still runs elsewhere, and stays the mode's fallback). A full rollout,
#: the canary's advance, or a rollback that gives robots a model back puts it in production;
#: production -> production: a model in production reached more robots. A rollback that leaves
#: no robot on its model retires it (a pending deployment's candidate too; a retired one stays
#: retired). A retired model may be promoted again.
MODEL = StateMachine(
    ModelStatus,
    edges={
        _C: {_A, _P, _R},
        _A: {_P, _R},
        _P: {_P, _R},
        _R: {_A, _P},
    },
    initial=_C,
    subject=lambda model: f"model {model.version}",
    error=RolloutStateError,
)
#: The statuses a canary start approves (the others keep theirs).
APPROVES = frozenset({_C, _R})


def robots_in_scope(session: Session, scope: DeploymentScope, target: str | None) -> list[Robot]:
    query = select(Robot).order_by(Robot.id)
    if scope == DeploymentScope.ROBOT:
        if not target:
            raise ValueError("target: a robot id is required for scope 'robot'")
        query = query.where(Robot.id == target)
    elif scope == DeploymentScope.WARD:
        if not target:
            raise ValueError("target: a ward is required for scope 'ward'")
        query = query.where(Robot.ward == target)
    robots = list(session.scalars(query))
    if not robots:
        raise ValueError(f"target: no robot in {scope.value} {target or ''}".strip())
    return robots


def _capable(session: Session, deployment: Deployment, robots: list[Robot]) -> list[Robot]:
    """The robots that can feed the deployment's model (their inputs may have changed since the
    promotion: checked again at every assignment). Refuses, or with only_capable skips, the
    others."""
    model = session.get(ModelVersion, deployment.model_version_id)
    checked = capability.qualify(robots, model)
    refused = [q for q in checked if not q.qualifies]
    if not refused:
        return robots
    if not deployment.rollout.get("only_capable"):
        raise CapabilityError(capability.refusal(model, refused, len(checked)))
    skipped = {**deployment.rollout.get("skipped", {}), **{q.robot_id: q.reason for q in refused}}
    deployment.rollout = {**deployment.rollout, "skipped": skipped}
    keep = {q.robot_id for q in checked if q.qualifies}
    return [r for r in robots if r.id in keep]


def _assign(session: Session, deployment: Deployment, robot_ids: list[str]) -> list[str]:
    previous = dict(deployment.rollout["previous"])
    robots = list(session.scalars(select(Robot).where(Robot.id.in_(robot_ids))))
    robots = _capable(session, deployment, robots)
    robot_ids = [r.id for r in robots]
    for robot in robots:
        if deployment.shadow:
            previous.setdefault(robot.id, robot.shadow_model_id)
            robot.shadow_model_id = deployment.model_version_id
        else:
            previous.setdefault(robot.id, robot.assigned_model_id)
            robot.assigned_model_id = deployment.model_version_id
    assigned = sorted(set(deployment.rollout["assigned"]) | set(robot_ids))
    deployment.rollout = {**deployment.rollout, "previous": previous, "assigned": assigned}
    return robot_ids


def _supersede_older(session: Session, deployment: Deployment) -> None:
    mine = set(deployment.rollout["assigned"])
    older = session.scalars(
        select(Deployment).where(
            Deployment.id != deployment.id,
            Deployment.shadow == deployment.shadow,
            Deployment.status.in_(LIVE),
        )
    )
    for other in older:
        theirs = set((other.rollout or {}).get("assigned", []))
        if theirs and theirs <= mine:
            ROLLOUT.move(other, DeploymentStatus.SUPERSEDED)


def _start(session: Session, deployment: Deployment) -> list[str]:
    """Assign the canary (or every robot of a single-robot scope). Returns changed robot ids."""
    robots = deployment.rollout["robots"]
    model = session.get(ModelVersion, deployment.model_version_id)
    if deployment.shadow or len(robots) == 1:
        ROLLOUT.move(deployment, DeploymentStatus.ACTIVE)
        changed = _assign(session, deployment, robots)
        if not deployment.shadow:
            MODEL.move(model, ModelStatus.PRODUCTION)
        _supersede_older(session, deployment)
        return changed
    ROLLOUT.move(deployment, DeploymentStatus.CANARY)
    if MODEL.state_of(model) in APPROVES:
        MODEL.move(model, ModelStatus.APPROVED)
    return _assign(session, deployment, [deployment.rollout["canary"]])


def promote(
    session: Session,
    model: ModelVersion,
    user: User,
    scope: DeploymentScope,
    target: str | None,
    gate: dict,
    canary_robot_id: str | None = None,
    comment: str | None = None,
    shadow: bool = False,
    require_second_approver: bool = False,
    only_capable: bool = False,
) -> tuple[Deployment, list[str]]:
    """Create a deployment of a model whose gate passed; returns it and the robots to notify.

    Every robot of the scope must feed the model's inputs (409 naming those that cannot);
    with `only_capable` a ward or fleet scope is narrowed to the robots that can.
    """
    if not shadow and not gate.get("passed"):
        failed = [f"{c['name']} ({c['detail']})" for c in gate.get("checks", []) if not c["passed"]]
        raise RolloutError(f"gate failed: {'; '.join(failed)}")
    in_scope = robots_in_scope(session, scope, target)
    if canary_robot_id is not None and canary_robot_id not in {r.id for r in in_scope}:
        raise ValueError(f"canary_robot_id: robot {canary_robot_id} is not in the scope")
    checked = capability.qualify(in_scope, model)
    refused = [q for q in checked if not q.qualifies]
    narrow = only_capable and scope != DeploymentScope.ROBOT
    if refused and (not narrow or len(refused) == len(checked)):
        raise CapabilityError(capability.refusal(model, refused, len(checked)))
    canary_refused = next((q for q in refused if q.robot_id == canary_robot_id), None)
    if canary_refused is not None:
        raise CapabilityError(f"canary_robot_id: {canary_refused.reason}")
    robots = [q.robot_id for q in checked if q.qualifies]
    deployment = Deployment(
        model_version_id=model.id,
        previous_model_version_id=None,
        scope=scope,
        target=target,
        shadow=shadow,
        status=ROLLOUT.initial,
        gate_report=gate,
        approved_by_id=user.id,
        comment=comment,
        created_by_id=user.id,
        rollout={
            "robots": robots,
            "canary": canary_robot_id or robots[0],
            "previous": {},
            "assigned": [],
            **(
                {"only_capable": True, "skipped": {q.robot_id: q.reason for q in refused}}
                if narrow
                else {}
            ),
        },
    )
    session.add(deployment)
    session.flush()
    first = session.get(Robot, deployment.rollout["canary"])
    deployment.previous_model_version_id = (
        first.shadow_model_id if shadow else first.assigned_model_id
    )
    if require_second_approver and not shadow:
        return deployment, []
    return deployment, _start(session, deployment)


def approve(session: Session, deployment: Deployment, user: User) -> list[str]:
    """The second approver's sign-off starts a pending deployment."""
    if deployment.status != DeploymentStatus.PENDING_APPROVAL:
        raise RolloutError(f"deployment {deployment.id} is {deployment.status}, not pending")
    if user.id in (deployment.approved_by_id, deployment.created_by_id):
        raise RolloutError("the second approver must be a different engineer")
    deployment.second_approver_id = user.id
    return _start(session, deployment)


def advance(session: Session, deployment: Deployment) -> list[str]:
    """Canary -> every robot of the scope, once the canary runs the new version."""
    if deployment.status != DeploymentStatus.CANARY:
        raise RolloutError(f"deployment {deployment.id} is {deployment.status}, not canary")
    model = session.get(ModelVersion, deployment.model_version_id)
    canary = session.get(Robot, deployment.rollout["canary"])
    if canary.running_model_version != model.version:
        raise RolloutError(
            f"canary robot {canary.id} runs {canary.running_model_version or 'no model'}, "
            f"not {model.version} yet"
        )
    ROLLOUT.move(deployment, DeploymentStatus.ACTIVE)
    rest = [r for r in deployment.rollout["robots"] if r not in deployment.rollout["assigned"]]
    changed = _assign(session, deployment, rest)
    MODEL.move(model, ModelStatus.PRODUCTION)
    _supersede_older(session, deployment)
    return changed


def rollback(
    session: Session, deployment: Deployment, reason: str, user: User | None = None
) -> list[str]:
    """Give every robot of the deployment back what it had before (if it still runs this one).

    A robot that had no model before gets its mode's keypoints-only fallback instead: left
    unassigned it would go on running the rolled-back model, which is what a rollback must end.
    What the robots run afterwards has a live deployment row: one per restored model, unless a
    live deployment of that model holds them already (`_record_restored`).
    """
    _guard_last_fallback(session, deployment)
    ROLLOUT.move(deployment, DeploymentStatus.ROLLED_BACK)
    deployment.rolled_back_at = utcnow()
    deployment.rollback_reason = reason
    previous = (deployment.rollout or {}).get("previous", {})
    model = session.get(ModelVersion, deployment.model_version_id)
    replacement = capability.fallback_model(session, model.mode, exclude=model.id)
    restored_to: dict[str, int | None] = {}
    shadow_restored: dict[str, int | None] = {}
    changed = []
    for robot in session.scalars(select(Robot).where(Robot.id.in_(list(previous)))):
        if deployment.shadow and robot.shadow_model_id == deployment.model_version_id:
            robot.shadow_model_id = shadow_restored[robot.id] = previous[robot.id]
            changed.append(robot.id)
        elif not deployment.shadow and robot.assigned_model_id == deployment.model_version_id:
            restored_id = previous[robot.id]
            if restored_id is None and replacement is not None:
                restored_id = replacement.id
            robot.assigned_model_id = restored_to[robot.id] = restored_id
            changed.append(robot.id)
            restored = session.get(ModelVersion, restored_id) if restored_id else None
            if restored is not None:
                MODEL.move(restored, ModelStatus.PRODUCTION)
    if restored_to:
        deployment.rollout = {**deployment.rollout, "restored": restored_to}
    still_used = session.scalars(
        select(Robot.id).where(Robot.assigned_model_id == model.id).limit(1)
    ).first()
    if not deployment.shadow and still_used is None and MODEL.state_of(model) != _R:
        MODEL.move(model, ModelStatus.RETIRED)
    _record_restored(session, deployment, shadow_restored or restored_to, reason, user)
    return changed


def _record_restored(
    session: Session,
    deployment: Deployment,
    restored_to: dict[str, int | None],
    reason: str,
    user: User | None,
) -> None:
    """A live deployment row for what the rolled-back robots run now, one per restored model:
    without it the fleet's deployments would all be rolled back or superseded while the robots
    run a model. Robots back on no model, or held by a live deployment of their restored model
    already (e.g. the ward rollout a canary interrupted), need none. The row is created through
    the rollout machine (pending, then active: nothing is left to approve) and names the
    rolled-back deployment; rolling it back in turn gives the robots the rolled-back model."""
    by_model: dict[int, list[str]] = {}
    for robot_id, model_id in sorted(restored_to.items()):
        if model_id is not None:
            by_model.setdefault(model_id, []).append(robot_id)
    if not by_model:
        return
    live = session.scalars(
        select(Deployment).where(
            Deployment.id != deployment.id,
            Deployment.shadow == deployment.shadow,
            Deployment.status.in_(LIVE),
        )
    )
    held = {
        (other.model_version_id, robot_id)
        for other in live
        for robot_id in (other.rollout or {}).get("assigned", [])
    }
    everyone = set((deployment.rollout or {}).get("assigned", []))
    rows = []
    for model_id, robots in by_model.items():
        robots = [r for r in robots if (model_id, r) not in held]
        if not robots:
            continue
        if set(robots) == everyone:
            scope, target = DeploymentScope(deployment.scope), deployment.target
        elif len(robots) == 1:
            scope, target = DeploymentScope.ROBOT, robots[0]
        else:
            scope, target = DeploymentScope(deployment.scope), deployment.target
        row = Deployment(
            model_version_id=model_id,
            previous_model_version_id=deployment.model_version_id,
            scope=scope,
            target=target,
            shadow=deployment.shadow,
            gate_report={},
            approved_by_id=user.id if user else None,
            created_by_id=user.id if user else None,
            comment=f"restored by the rollback of deployment {deployment.id}: {reason}",
            rollout={
                "robots": robots,
                "canary": None,
                "previous": dict.fromkeys(robots, deployment.model_version_id),
                "assigned": robots,
                "restored_from": deployment.id,
            },
        )
        ROLLOUT.start(row)
        ROLLOUT.move(row, DeploymentStatus.ACTIVE)
        session.add(row)
        rows.append(row)
    if rows:
        session.flush()
        deployment.rollout = {**deployment.rollout, "restored_by": [r.id for r in rows]}


def _guard_last_fallback(session: Session, deployment: Deployment) -> None:
    """Refuse a rollback that would retire the last keypoints-only production model of a mode:
    every robot of that mode whose model needs depth or floor falls back to it."""
    model = session.get(ModelVersion, deployment.model_version_id)
    if (
        deployment.shadow
        or ModelStatus(model.status) != ModelStatus.PRODUCTION
        or not capability.is_fallback_candidate(model)
    ):
        return
    previous = (deployment.rollout or {}).get("previous", {})
    users = session.scalars(select(Robot).where(Robot.assigned_model_id == model.id)).all()
    if any(robot.id not in previous for robot in users):
        return  # another deployment's robots keep it: it is not retired
    restored = [session.get(ModelVersion, previous[r.id]) for r in users if previous[r.id]]
    if any(
        m is not None and m.mode == model.mode and capability.is_fallback_candidate(m)
        for m in restored
    ):
        return  # the rollback promotes another keypoints-only model of the mode back
    if capability.fallback_model(session, model.mode, exclude=model.id) is not None:
        return
    raise RolloutError(
        f"cannot roll back deployment {deployment.id}: {model.version} is the last promoted "
        f"keypoints-only {model.mode} model, the fallback of every {model.mode} robot whose "
        f"model needs depth or floor measures; promote another keypoints-only {model.mode} "
        "model first"
    )
