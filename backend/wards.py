"""Ward isolation, written once: which ward a user is confined to, and the query clauses that
scope every resource carrying a ward.

The rule (the one alarms always followed): a nurse with a ward sees that ward only; a nurse
without one (a float nurse), engineers, admins and annotators see every ward. Which roles may
call a route at all is `backend.permissions`; this decides which rows they see through it.

What carries a ward: an alarm (its ward when raised), a robot (`Robot.ward`), a transport and a
video recorded by a robot (the robot's ward), and a frame (its video's). A video that no robot
recorded (imported, a dataset) belongs to no ward, so a ward-confined user does not see it. A
list leaves out what the user may not see; a single resource of another ward answers 404, as
if it did not exist (a 403 would confirm the id).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from sqlalchemy import ColumnElement, Select, select, true
from sqlalchemy.orm import Session

from backend.models.alarms import Alarm
from backend.models.robots import Robot, Transport
from backend.models.users import Role
from backend.models.videos import Video


class HasWard(Protocol):
    role: Role
    ward: str | None


def ward_of(user: HasWard) -> str | None:
    """The one ward `user` is confined to, or None for every ward."""
    if user.role == Role.NURSE and user.ward:
        return user.ward
    return None


def sees_ward(user: HasWard, ward: str | None) -> bool:
    confined = ward_of(user)
    return confined is None or confined == ward


def _robots_of(ward: str) -> Select:
    return select(Robot.id).where(Robot.ward == ward)


def alarms_visible(user: HasWard) -> ColumnElement[bool]:
    ward = ward_of(user)
    return true() if ward is None else Alarm.ward == ward


def robots_visible(user: HasWard) -> ColumnElement[bool]:
    ward = ward_of(user)
    return true() if ward is None else Robot.ward == ward


def transports_visible(user: HasWard) -> ColumnElement[bool]:
    ward = ward_of(user)
    return true() if ward is None else Transport.robot_id.in_(_robots_of(ward))


def videos_visible(user: HasWard) -> ColumnElement[bool]:
    ward = ward_of(user)
    return true() if ward is None else Video.robot_id.in_(_robots_of(ward))


def visible_robot(session: Session, user: HasWard, robot_id: str) -> Robot | None:
    return session.scalars(select(Robot).where(Robot.id == robot_id, robots_visible(user))).first()


def visible_transport(session: Session, user: HasWard, transport_id: str) -> Transport | None:
    return session.scalars(
        select(Transport).where(Transport.id == transport_id, transports_visible(user))
    ).first()


def visible_video(session: Session, user: HasWard, video_id: int) -> Video | None:
    return session.scalars(select(Video).where(Video.id == video_id, videos_visible(user))).first()


def list_robots(session: Session, user: HasWard) -> Sequence[Robot]:
    return session.scalars(select(Robot).where(robots_visible(user)).order_by(Robot.id)).all()


def list_transports(
    session: Session,
    user: HasWard,
    robot_id: str | None = None,
    active: bool | None = None,
    limit: int = 100,
) -> Sequence[Transport]:
    """Newest first; `active`: only those under way (True) or only ended ones (False)."""
    query = select(Transport).where(transports_visible(user))
    if robot_id:
        query = query.where(Transport.robot_id == robot_id)
    if active is not None:
        query = query.where(
            Transport.ended_at.is_(None) if active else Transport.ended_at.is_not(None)
        )
    return session.scalars(query.order_by(Transport.started_at.desc()).limit(limit)).all()
