"""Alarm queries, in one place."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models.alarms import Alarm, AlarmEvent, AlarmKind, AlarmState
from backend.models.users import Role, User


def visible_to(user: User):
    """Nurses see their own ward (every ward when they have none); others see all."""
    if user.role == Role.NURSE and user.ward:
        return Alarm.ward == user.ward
    return True


def list_alarms(
    session: Session,
    user: User,
    state: AlarmState | None = None,
    kind: AlarmKind | None = None,
    ward: str | None = None,
    robot_id: str | None = None,
    since: datetime | None = None,
    until: datetime | None = None,
    limit: int = 200,
) -> Sequence[Alarm]:
    query = select(Alarm).where(visible_to(user))
    if state is not None:
        query = query.where(Alarm.state == state)
    if kind is not None:
        query = query.where(Alarm.kind == kind)
    if ward is not None:
        query = query.where(Alarm.ward == ward)
    if robot_id is not None:
        query = query.where(Alarm.robot_id == robot_id)
    if since is not None:
        query = query.where(Alarm.raised_at >= since)
    if until is not None:
        query = query.where(Alarm.raised_at < until)
    return session.scalars(query.order_by(Alarm.raised_at.desc()).limit(limit)).unique().all()


def unresolved_for(session: Session, user: User) -> Sequence[Alarm]:
    return (
        session.scalars(
            select(Alarm)
            .where(visible_to(user), Alarm.state != AlarmState.RESOLVED)
            .order_by(Alarm.raised_at)
        )
        .unique()
        .all()
    )


def get_visible(session: Session, user: User, alarm_id: int) -> Alarm | None:
    return session.scalars(select(Alarm).where(Alarm.id == alarm_id, visible_to(user))).first()


def events_of(session: Session, alarm_id: int) -> Sequence[AlarmEvent]:
    return session.scalars(
        select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
    ).all()
