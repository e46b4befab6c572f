"""Model registry, promotion and fleet routes for engineers, and the robots' model download."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Header, HTTPException, Query, status
from fastapi.responses import FileResponse

from backend import wards
from backend.deps import MAX_DB_INT, CurrentUser, SessionDep, SettingsDep
from backend.models.registry import Deployment, ModelVersion
from backend.models.robots import Robot
from backend.models.users import User
from backend.registry import queries, rollout
from backend.registry.capability import fallback_for
from backend.registry.gate import gate_report
from backend.registry.schemas import (
    Comparison,
    DeploymentOut,
    FleetRobot,
    ModelDetail,
    ModelSummary,
    PromoteIn,
    RollbackIn,
    ShadowIn,
)
from backend.security import robot_token_matches
from backend.services import ServicesDep
from backend.settings import Settings
from backend.unit_of_work import fleet_changed, push_assignments
from vigil.model_file import MANIFEST_NAME

router = APIRouter(prefix="/api", tags=["registry"])


def _model(session, model_id: int) -> ModelVersion:
    model = session.get(ModelVersion, model_id)
    if model is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"model {model_id} not found")
    return model


def _deployment(session, deployment_id: int) -> Deployment:
    deployment = session.get(Deployment, deployment_id)
    if deployment is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"deployment {deployment_id} not found")
    return deployment


def _change(session: SessionDep, change: Callable[[Any], tuple[Any, list[str]]]):
    """Run a rollout change in the request's unit of work; once it is committed, the robots
    it names get their assignments and the fleet pages reload (the deployments changed)."""
    try:
        result, robots = change(session)
    except rollout.RolloutError as error:
        raise HTTPException(status.HTTP_409_CONFLICT, str(error)) from None
    except ValueError as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(error)) from None
    session.flush()
    push_assignments(session, robots)
    fleet_changed(session, robots)
    return result


@router.get("/models")
def list_models(session: SessionDep, user: CurrentUser) -> list[ModelSummary]:
    return queries.list_models(session)


@router.get("/models/compare")
def compare_models(
    session: SessionDep, user: CurrentUser, a: Annotated[int, Query()], b: Annotated[int, Query()]
) -> Comparison:
    model_a, model_b = _model(session, a), _model(session, b)
    rows, events = queries.compare(model_a, model_b)
    return Comparison(
        a=queries.detail(session, model_a),
        b=queries.detail(session, model_b),
        rows=rows,
        events=events,
    )


@router.get("/models/{model_id}")
def get_model(model_id: int, session: SessionDep, user: CurrentUser) -> ModelDetail:
    return queries.detail(session, _model(session, model_id))


@router.get("/models/{model_id}/plots/{name}", response_class=FileResponse)
def get_plot(model_id: int, name: str, session: SessionDep, user: CurrentUser) -> FileResponse:
    directory = queries.plots_dir(_model(session, model_id))
    if not name.isidentifier():
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "name: not a plot name")
    path = directory / f"{name}.png"
    if not path.is_file():
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"model {model_id} has no plot {name}")
    return FileResponse(path, media_type="image/png")


@router.get("/models/{model_id}/gate")
def get_gate(model_id: int, session: SessionDep, settings: SettingsDep, user: CurrentUser) -> dict:
    """The gate decision this model would get now, with its figures."""
    model = _model(session, model_id)
    return gate_report(model, settings.gate_false_alarm_budget, settings.gate_latency_ms)


def _report(model: ModelVersion, settings: Settings) -> dict:
    return gate_report(model, settings.gate_false_alarm_budget, settings.gate_latency_ms)


@router.post("/models/{model_id}/promote", status_code=status.HTTP_201_CREATED)
def promote(
    model_id: int, body: PromoteIn, settings: SettingsDep, user: CurrentUser, session: SessionDep
) -> DeploymentOut:
    """Engineer sign-off: passes the gate, then rolls out (canary first for several robots)."""
    user_id = user.id

    def change(session):
        model, signer = _model(session, model_id), session.get(User, user_id)
        deployment, robots = rollout.promote(
            session,
            model,
            signer,
            body.scope,
            body.target,
            _report(model, settings),
            canary_robot_id=body.canary_robot_id,
            comment=body.comment,
            require_second_approver=settings.require_second_approver,
            only_capable=body.only_capable,
        )
        return queries.deployment_out(session, deployment), robots

    return _change(session, change)


@router.post("/models/{model_id}/shadow", status_code=status.HTTP_201_CREATED)
def start_shadow(
    model_id: int, body: ShadowIn, settings: SettingsDep, user: CurrentUser, session: SessionDep
) -> DeploymentOut:
    """Run a candidate beside production on robots: decisions stored, never alarmed."""
    user_id = user.id

    def change(session):
        model, signer = _model(session, model_id), session.get(User, user_id)
        deployment, robots = rollout.promote(
            session,
            model,
            signer,
            body.scope,
            body.target,
            _report(model, settings),
            comment=body.comment,
            shadow=True,
            only_capable=body.only_capable,
        )
        return queries.deployment_out(session, deployment), robots

    return _change(session, change)


@router.get("/deployments")
def list_deployments(session: SessionDep, user: CurrentUser) -> list[DeploymentOut]:
    return queries.list_deployments(session)


@router.post("/deployments/{deployment_id}/approve")
def approve_deployment(
    deployment_id: int, settings: SettingsDep, user: CurrentUser, session: SessionDep
) -> DeploymentOut:
    user_id = user.id

    def change(session):
        deployment = _deployment(session, deployment_id)
        robots = rollout.approve(session, deployment, session.get(User, user_id))
        return queries.deployment_out(session, deployment), robots

    return _change(session, change)


@router.post("/deployments/{deployment_id}/advance")
def advance_deployment(
    deployment_id: int, settings: SettingsDep, user: CurrentUser, session: SessionDep
) -> DeploymentOut:
    """Canary is healthy: roll out to the remaining robots of the scope."""

    def change(session):
        deployment = _deployment(session, deployment_id)
        robots = rollout.advance(session, deployment)
        return queries.deployment_out(session, deployment), robots

    return _change(session, change)


@router.post("/deployments/{deployment_id}/rollback")
def rollback_deployment(
    deployment_id: int,
    body: RollbackIn,
    settings: SettingsDep,
    user: CurrentUser,
    session: SessionDep,
) -> DeploymentOut:
    """Every robot of the deployment gets back the model it had before; a live deployment row
    of each restored model says what they run now."""
    username, user_id = user.username, user.id

    def change(session):
        deployment = _deployment(session, deployment_id)
        robots = rollout.rollback(
            session, deployment, f"{body.reason} ({username})", user=session.get(User, user_id)
        )
        return queries.deployment_out(session, deployment), robots

    return _change(session, change)


@router.get("/fleet")
def fleet(
    session: SessionDep,
    user: CurrentUser,
    services: ServicesDep,
    model_id: Annotated[
        int | None,
        Query(ge=1, le=MAX_DB_INT, description="also say whether each robot can feed this model"),
    ] = None,
) -> list[FleetRobot]:
    """Target vs running version per robot, what it feeds, its fallback; with model_id, which
    robots qualify for that model (a promotion to the others is refused)."""
    registry = services.robots
    connected = {r for r in queries.robot_ids(session) if registry.socket(r) is not None}
    model = _model(session, model_id) if model_id is not None else None
    return queries.fleet(session, connected, model, scope=wards.robots_visible(user))


# --- robots: model download, authenticated by the robot's own token ------------------------


def _robot_model(session, robot_id: str, authorization: str, version: str) -> ModelVersion:
    scheme, _, token = authorization.partition(" ")
    robot = session.get(Robot, robot_id)
    if (
        scheme.lower() != "bearer"
        or robot is None
        or not robot_token_matches(robot.token_hash, token)
    ):
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "unknown robot or wrong robot token")
    model = queries.model_by_version(session, version)
    if model is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"model {version} not found")
    if model.id not in (robot.assigned_model_id, robot.shadow_model_id) and not _is_fallback_of(
        session, robot, model
    ):
        raise HTTPException(
            status.HTTP_403_FORBIDDEN, f"model {version} is not assigned to {robot_id}"
        )
    return model


def _is_fallback_of(session, robot: Robot, model: ModelVersion) -> bool:
    if robot.assigned_model_id is None:
        return False
    fallback = fallback_for(session, session.get(ModelVersion, robot.assigned_model_id))
    return fallback is not None and fallback.id == model.id


RobotIdHeader = Annotated[str, Header(alias="X-Robot-Id", min_length=1, max_length=64)]
AuthorizationHeader = Annotated[str, Header()]


@router.get("/robot/models/{version}/file", response_class=FileResponse)
def download_model(
    version: str, session: SessionDep, robot_id: RobotIdHeader, authorization: AuthorizationHeader
) -> FileResponse:
    """The ONNX file of a model assigned to the calling robot; check it against the sha256 of
    the assignment (also sent as the X-Model-Sha256 header) before loading it."""
    model = _robot_model(session, robot_id, authorization, version)
    path = Path(model.file_path)
    if not path.is_file():
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"model file of {version} is missing")
    return FileResponse(
        path, media_type="application/octet-stream", headers={"X-Model-Sha256": model.sha256}
    )


@router.get("/robot/models/{version}/manifest")
def download_manifest(
    version: str, session: SessionDep, robot_id: RobotIdHeader, authorization: AuthorizationHeader
) -> dict:
    model = _robot_model(session, robot_id, authorization, version)
    manifest_path = Path(model.file_path).parent / MANIFEST_NAME
    if not manifest_path.is_file():
        return model.manifest
    return json.loads(manifest_path.read_text())
