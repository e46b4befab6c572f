"""The outbox's SQL (alarm distribution)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.models.alarms import AlarmDisposition, AlarmMessage, MessageStatus
from backend.models.robots import Robot


def due(session: Session, limit: int) -> list[AlarmMessage]:
    """Pending messages, oldest change first (the order the Alert Manager must see)."""
    return list(
        session.scalars(
            select(AlarmMessage)
            .where(AlarmMessage.status == MessageStatus.PENDING)
            .order_by(AlarmMessage.id)
            .limit(limit)
        )
    )


def by_ids(session: Session, ids: list[int]) -> list[AlarmMessage]:
    return list(session.scalars(select(AlarmMessage).where(AlarmMessage.id.in_(ids))))


def by_control_id(session: Session, control_id: str) -> AlarmMessage | None:
    query = select(AlarmMessage).where(AlarmMessage.control_id == control_id)
    return session.scalars(query).first()


def disposition_recorded(session: Session, control_id: str) -> bool:
    found = session.scalars(
        select(AlarmDisposition.id).where(AlarmDisposition.control_id == control_id)
    ).first()
    return found is not None


def pending_by_ward(session: Session, destination: str) -> dict[str, int]:
    rows = session.execute(
        select(AlarmMessage.ward, func.count())
        .where(
            AlarmMessage.status == MessageStatus.PENDING,
            AlarmMessage.destination == destination,
        )
        .group_by(AlarmMessage.ward)
    ).all()
    return {ward: count for ward, count in rows}


def counts(session: Session) -> dict[str, int]:
    rows = session.execute(
        select(AlarmMessage.status, func.count()).group_by(AlarmMessage.status)
    ).all()
    return {str(status): count for status, count in rows}


def known_wards(session: Session) -> list[str]:
    return sorted(w for w in session.scalars(select(Robot.ward).distinct()) if w)
