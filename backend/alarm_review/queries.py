"""Queries for alarm review: history with filters, frames around an alarm, alarms in a period."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import Row, Select, and_, func, or_, select
from sqlalchemy.orm import Session

from backend.models import Alarm, AlarmEvent, Frame
from backend.models.alarms import AlarmState

MAX_REPLAY_FRAMES = 3000


@dataclass(frozen=True, slots=True)
class HistoryFilter:
    ward: str | None = None
    robot_id: str | None = None
    kind: str | None = None
    verdict: str | None = None
    model_version: str | None = None
    since: datetime | None = None
    until: datetime | None = None

    def apply(self, query: Select) -> Select:
        conditions = [
            Alarm.ward == self.ward if self.ward else None,
            Alarm.robot_id == self.robot_id if self.robot_id else None,
            Alarm.kind == self.kind if self.kind else None,
            Alarm.verdict == self.verdict if self.verdict else None,
            Alarm.model_version == self.model_version if self.model_version else None,
            Alarm.raised_at >= self.since if self.since else None,
            Alarm.raised_at < self.until if self.until else None,
        ]
        return query.where(*(c for c in conditions if c is not None))


def alarm_history(
    session: Session, filters: HistoryFilter, limit: int, offset: int
) -> tuple[int, list[Alarm]]:
    total = session.scalar(filters.apply(select(func.count(Alarm.id))))
    rows = session.scalars(
        filters.apply(select(Alarm))
        .order_by(Alarm.raised_at.desc(), Alarm.id.desc())
        .limit(limit)
        .offset(offset)
    )
    return total or 0, list(rows)


REPLAY_COLUMNS = (
    Frame.seq,
    Frame.index,
    Frame.ts,
    Frame.keypoints,
    Frame.depth,
    Frame.decision,
    Frame.scores,
    Frame.model_version,
)


def frames_around(session: Session, alarm: Alarm, before_s: float, after_s: float) -> list[Row]:
    """The alarm's stored frames plus before_s seconds before and after_s after, in order: rows
    of REPLAY_COLUMNS (no ORM objects: a replay has 600 frames and more). The ts range is the
    partition key: PostgreSQL reads one or two day partitions."""
    if alarm.first_frame_ts is None:
        return []
    start = alarm.first_frame_ts - before_s
    end = (alarm.last_frame_ts or alarm.first_frame_ts) + after_s
    query = select(*REPLAY_COLUMNS).where(Frame.ts >= start, Frame.ts <= end)
    if alarm.video_id is not None:
        query = query.where(Frame.video_id == alarm.video_id)
    else:
        query = query.where(Frame.robot_id == alarm.robot_id)
    return list(session.execute(query.order_by(Frame.ts, Frame.id).limit(MAX_REPLAY_FRAMES)))


def alarms_between(
    session: Session, since: datetime, until: datetime, ward: str | None
) -> list[Alarm]:
    query = select(Alarm).where(Alarm.raised_at >= since, Alarm.raised_at < until)
    if ward:
        query = query.where(Alarm.ward == ward)
    return list(session.scalars(query))


def handover_alarms(
    session: Session, since: datetime, until: datetime, ward: str | None
) -> list[Alarm]:
    """Every alarm unresolved now, plus every alarm raised in [since, until)."""
    query = select(Alarm).where(
        or_(
            Alarm.state != AlarmState.RESOLVED,
            and_(Alarm.raised_at >= since, Alarm.raised_at < until),
        )
    )
    if ward:
        query = query.where(Alarm.ward == ward)
    return list(session.scalars(query).unique())


def ever_missed(session: Session, alarm_ids: list[int]) -> set[int]:
    """Of these alarms, those the escalation chain ever moved to missed (audit trail)."""
    if not alarm_ids:
        return set()
    found: set[int] = set()
    for start in range(0, len(alarm_ids), 500):
        chunk = alarm_ids[start : start + 500]
        found.update(
            session.scalars(
                select(AlarmEvent.alarm_id).where(
                    AlarmEvent.alarm_id.in_(chunk), AlarmEvent.action == "miss"
                )
            )
        )
    return found
