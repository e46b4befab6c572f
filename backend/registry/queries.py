"""Registry reads in one place: models, deployments, the fleet's target vs running versions."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import ColumnElement, func, select
from sqlalchemy.orm import Session

from backend.models.alarms import Alarm, AlarmKind, AlarmState
from backend.models.registry import Deployment, DeploymentStatus, ModelVersion
from backend.models.robots import Robot
from backend.registry import capability
from backend.registry.autorollback import rejection_share
from backend.registry.schemas import DeploymentOut, FleetRobot, ModelDetail, ModelSummary

GOLD_HEADLINE = (
    "falls_detected",
    "falls_total",
    "adl_false_alarms",
    "adl_total",
    "frame_recall",
    "frame_f1",
    "median_time_to_alarm_s",
)


def _assigned_counts(session: Session) -> dict[int, int]:
    return dict(
        session.execute(
            select(Robot.assigned_model_id, func.count())
            .where(Robot.assigned_model_id.is_not(None))
            .group_by(Robot.assigned_model_id)
        ).all()
    )


class Reach:
    """Where models run: robots assigned per model, the fleet's size, live canaries. Read
    once per request so that a model's status can be said in true words."""

    def __init__(self, session: Session) -> None:
        self.assigned = _assigned_counts(session)
        self.fleet = session.scalar(select(func.count()).select_from(Robot)) or 0
        canaries = session.scalars(
            select(Deployment).where(
                Deployment.status == DeploymentStatus.CANARY, Deployment.shadow.is_(False)
            )
        )
        self.canary = {d.model_version_id: (d.rollout or {}).get("canary") for d in canaries}


def summary(model: ModelVersion, reach: Reach | None = None) -> ModelSummary:
    gold = (model.metrics or {}).get("gold")
    assigned = reach.assigned.get(model.id, 0) if reach else 0
    return ModelSummary(
        id=model.id,
        version=model.version,
        mode=model.mode,
        kind=model.kind,
        status=model.status,
        sha256=model.sha256,
        created_at=model.created_at,
        job_id=model.job_id,
        threshold=model.manifest["threshold"],
        delay_ms=model.manifest["delay_ms"],
        gold={k: gold.get(k) for k in GOLD_HEADLINE} if gold else None,
        parent=(model.lineage or {}).get("parent"),
        robots_assigned=assigned,
        robots_in_fleet=reach.fleet if reach else 0,
        canary_robot=reach.canary.get(model.id) if reach else None,
        inputs=capability.model_needs(model),
        keypoints_only=capability.is_fallback_candidate(model),
    )


def plots_dir(model: ModelVersion) -> Path:
    return Path(model.file_path).parent / "plots"


def detail(session: Session, model: ModelVersion) -> ModelDetail:
    base = summary(model, Reach(session))
    directory = plots_dir(model)
    plots = sorted(p.stem for p in directory.glob("*.png")) if directory.is_dir() else []
    return ModelDetail(
        **base.model_dump(),
        manifest=model.manifest,
        metrics=model.metrics,
        lineage=model.lineage,
        plots=plots,
    )


def list_models(session: Session) -> list[ModelSummary]:
    reach = Reach(session)
    models = session.scalars(select(ModelVersion).order_by(ModelVersion.created_at.desc()))
    return [summary(m, reach) for m in models]


def model_by_version(session: Session, version: str) -> ModelVersion | None:
    return session.scalars(select(ModelVersion).where(ModelVersion.version == version)).first()


def sha256_of_versions(session: Session, versions: set[str]) -> dict[str, str]:
    """version -> the registry's sha256, for the versions the registry knows."""
    if not versions:
        return {}
    rows = session.execute(
        select(ModelVersion.version, ModelVersion.sha256).where(ModelVersion.version.in_(versions))
    )
    return {version: sha256 for version, sha256 in rows}


def deployment_out(session: Session, deployment: Deployment) -> DeploymentOut:
    out = DeploymentOut.model_validate(deployment)
    out.model_version = session.get(ModelVersion, deployment.model_version_id).version
    if not deployment.shadow:
        out.alarms_rejected, out.alarms_judged = rejection_share(session, deployment)
    return out


def list_deployments(session: Session, limit: int = 100) -> list[DeploymentOut]:
    rows = session.scalars(select(Deployment).order_by(Deployment.id.desc()).limit(limit))
    return [deployment_out(session, d) for d in rows]


def fleet(
    session: Session,
    connected: set[str],
    model: ModelVersion | None = None,
    scope: ColumnElement[bool] | None = None,
) -> list[FleetRobot]:
    """Every robot's target vs running version, its inputs and fallback; with `model`, whether
    each robot qualifies for it. `scope`: the caller's wards (backend.wards.robots_visible)."""
    models = {m.id: m for m in session.scalars(select(ModelVersion))}
    query = select(Robot) if scope is None else select(Robot).where(scope)
    robots = session.scalars(query.order_by(Robot.ward, Robot.id))
    degraded = set(
        session.scalars(
            select(Alarm.robot_id).where(
                Alarm.kind == AlarmKind.DETECTION_DEGRADED, Alarm.state != AlarmState.RESOLVED
            )
        )
    )
    fallbacks: dict = {}
    out = []
    for robot in robots:
        target_model = models.get(robot.assigned_model_id)
        target = target_model.version if target_model else None
        shadow = models.get(robot.shadow_model_id)
        fallback = capability.fallback_for(session, target_model, fallbacks)
        missing = capability.missing_for(robot, model) if model is not None else []
        out.append(
            FleetRobot(
                id=robot.id,
                name=robot.name,
                ward=robot.ward,
                connected=robot.id in connected,
                target_version=target,
                running_version=robot.running_model_version,
                shadow_version=shadow.version if shadow else None,
                running_sha256=robot.running_model_sha256,
                in_sync=in_sync(target_model, robot),
                agent_version=robot.agent_version,
                last_seen_at=robot.last_seen_at,
                inputs=robot.feeds,
                inputs_reported=robot.inputs is not None,
                fallback_version=fallback.version if fallback else None,
                target_feedable=target_model is None
                or not capability.missing_for(robot, target_model),
                detection_degraded=robot.id in degraded,
                behaviour_state=robot.behaviour_state,
                behaviour_since=robot.behaviour_since,
                behaviour_reason=robot.behaviour_reason,
                qualifies=None if model is None else not missing,
                missing_inputs=missing,
            )
        )
    return out


def in_sync(target: ModelVersion | None, robot: Robot) -> bool:
    """The robot runs its target: the version, and a file whose sha256 (as the robot computed
    it from the bytes it loaded) is the registry's. A robot that does not report the sha256 (an
    older agent) cannot be shown to run the registry's file: not in sync. A robot with no target
    is in sync only when it runs no model (after a rollback it may still run the old one)."""
    if target is None:
        return robot.running_model_version is None
    return (
        robot.running_model_version == target.version
        and robot.running_model_sha256 == target.sha256
    )


COMPARED = (
    ("falls_detected", "higher"),
    ("adl_false_alarms", "lower"),
    ("frame_recall", "higher"),
    ("frame_precision", "higher"),
    ("frame_f1", "higher"),
    ("fp", "lower"),
    ("fp_d", "lower"),
    ("fn", "lower"),
    ("fn_d", "lower"),
    ("event_f1", "higher"),
    ("median_time_to_alarm_s", "lower"),
    ("max_time_to_alarm_s", "lower"),
)


def compare(a: ModelVersion, b: ModelVersion) -> tuple[list[dict], list[dict]]:
    """Side-by-side gold-set figures (plus operating point and latency) and per-event results."""
    ga, gb = (a.metrics or {}).get("gold") or {}, (b.metrics or {}).get("gold") or {}
    rows = [
        {"metric": "threshold", "a": a.manifest["threshold"], "b": b.manifest["threshold"]},
        {"metric": "delay_ms", "a": a.manifest["delay_ms"], "b": b.manifest["delay_ms"]},
    ]
    la, lb = (a.metrics or {}).get("latency") or {}, (b.metrics or {}).get("latency") or {}
    rows.append(
        {
            "metric": "latency_p95_ms",
            "a": la.get("p95_ms"),
            "b": lb.get("p95_ms"),
            "better": "lower",
        }
    )
    for key, better in COMPARED:
        rows.append({"metric": key, "a": ga.get(key), "b": gb.get(key), "better": better})
    for row in rows:
        va, vb = row["a"], row["b"]
        numeric = isinstance(va, int | float) and isinstance(vb, int | float)
        row["delta"] = vb - va if numeric else None
        if numeric and "better" in row and va != vb:
            row["winner"] = "b" if (vb > va) == (row["better"] == "higher") else "a"
        else:
            row["winner"] = None
    events_a = {e["sequence"]: e for e in ga.get("events", [])}
    events_b = {e["sequence"]: e for e in gb.get("events", [])}
    events = [
        {"sequence": name, "a": events_a.get(name), "b": events_b.get(name)}
        for name in sorted(set(events_a) | set(events_b))
    ]
    return rows, events


def robot_ids(session: Session) -> list[str]:
    return list(session.scalars(select(Robot.id)))
