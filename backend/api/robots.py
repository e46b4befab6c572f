from datetime import datetime

from fastapi import APIRouter, HTTPException, Query, status
from pydantic import BaseModel, ConfigDict, Field

from backend import wards
from backend.deps import CurrentUser, SessionDep
from backend.models._types import utcnow
from backend.models.robots import Robot
from backend.security import hash_robot_token, new_robot_token
from backend.services import ServicesDep
from backend.unit_of_work import after_commit
from vigil.classes import TransportMode
from vigil.inputs import InputName
from vigil.protocol import CLOSE_UNAUTHORIZED

router = APIRouter(prefix="/api", tags=["robots"])


class RobotOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: str
    name: str
    ward: str
    has_token: bool
    assigned_model_id: int | None
    shadow_model_id: int | None
    running_model_version: str | None
    agent_version: str | None
    inputs: list[InputName] = Field(
        description="what the robot can feed a model (its last hello; keypoints only when it "
        "did not say)"
    )
    inputs_reported: bool = Field(description="false: an older agent, or it never connected")
    last_seen_at: datetime | None
    last_seq: int | None
    connected: bool = False


class RobotIn(BaseModel):
    id: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    name: str = Field(default="", max_length=128)
    ward: str = Field(min_length=1, max_length=64)


class RobotTokenOut(BaseModel):
    robot_id: str
    token: str = Field(description="shown once; only its hash is stored")


class TransportOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: str
    robot_id: str
    mode: TransportMode
    patient: str | None
    location: str | None
    started_at: datetime
    ended_at: datetime | None
    last_frame_at: datetime | None
    fps: float | None = Field(default=None, description="the source's frame rate, if it said")


def _robot_out(services: ServicesDep, robot: Robot) -> RobotOut:
    out = RobotOut.model_validate(
        {
            **robot.__dict__,
            "has_token": robot.token_hash is not None,
            "inputs": robot.feeds,
            "inputs_reported": robot.inputs is not None,
        }
    )
    out.connected = services.robots.socket(robot.id) is not None
    return out


@router.get("/robots")
def list_robots(session: SessionDep, user: CurrentUser, services: ServicesDep) -> list[RobotOut]:
    """The robots of the wards the caller sees (backend.wards)."""
    return [_robot_out(services, r) for r in wards.list_robots(session, user)]


@router.post("/robots", status_code=status.HTTP_201_CREATED)
def create_robot(body: RobotIn, session: SessionDep, user: CurrentUser) -> RobotTokenOut:
    if session.get(Robot, body.id) is not None:
        raise HTTPException(status.HTTP_409_CONFLICT, f"robot {body.id} already exists")
    token = new_robot_token()
    session.add(
        Robot(
            id=body.id,
            name=body.name,
            ward=body.ward,
            token_hash=hash_robot_token(token),
            token_created_at=utcnow(),
        )
    )
    return RobotTokenOut(robot_id=body.id, token=token)


def _robot(session: SessionDep, robot_id: str) -> Robot:
    robot = session.get(Robot, robot_id)
    if robot is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"robot {robot_id} not found")
    return robot


@router.get("/robots/{robot_id}")
def get_robot(
    robot_id: str, session: SessionDep, user: CurrentUser, services: ServicesDep
) -> RobotOut:
    robot = wards.visible_robot(session, user, robot_id)
    if robot is None:  # another ward's robot: as if it did not exist
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"robot {robot_id} not found")
    return _robot_out(services, robot)


def _close_live_connection(session: SessionDep, services: ServicesDep, robot_id: str, reason: str):
    """Once committed (a reconnect must already be refused), close the robot's live connection
    to this replica (4401): it authenticated with a token that is no longer valid, and must
    connect again with the current one."""
    registry = services.robots

    async def close() -> None:
        connection = registry.socket(robot_id)
        if connection is not None:
            await connection.close(CLOSE_UNAUTHORIZED, reason)

    after_commit(session, close)


@router.post("/robots/{robot_id}/token")
def rotate_token(
    robot_id: str, session: SessionDep, user: CurrentUser, services: ServicesDep
) -> RobotTokenOut:
    """A new token (shown once); the old one stops working and the robot's live connection to
    this replica is closed, as on revocation."""
    robot = _robot(session, robot_id)
    token = new_robot_token()
    robot.token_hash = hash_robot_token(token)
    robot.token_created_at = utcnow()
    _close_live_connection(session, services, robot_id, "robot token rotated")
    return RobotTokenOut(robot_id=robot_id, token=token)


@router.delete("/robots/{robot_id}/token", status_code=status.HTTP_204_NO_CONTENT)
def revoke_token(
    robot_id: str, session: SessionDep, user: CurrentUser, services: ServicesDep
) -> None:
    """Revoke the robot's token and close its live connection to this replica."""
    _robot(session, robot_id).token_hash = None
    _close_live_connection(session, services, robot_id, "robot token revoked")


@router.get("/transports")
def list_transports(
    session: SessionDep,
    user: CurrentUser,
    robot_id: str | None = None,
    active: bool | None = Query(default=None, description="only transports under way (true)"),
    limit: int = Query(default=100, ge=1, le=1000),
) -> list[TransportOut]:
    """The transports of the wards the caller sees (backend.wards), newest first."""
    transports = wards.list_transports(session, user, robot_id, active, limit)
    return [TransportOut.model_validate(t) for t in transports]


@router.get("/transports/{transport_id}")
def get_transport(transport_id: str, session: SessionDep, user: CurrentUser) -> TransportOut:
    transport = wards.visible_transport(session, user, transport_id)
    if transport is None:  # another ward's transport: as if it did not exist
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"transport {transport_id} not found")
    return TransportOut.model_validate(transport)
