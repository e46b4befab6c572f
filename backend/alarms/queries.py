"""Alarm queries, in one place."""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import contextmanager
from datetime import datetime
from typing import TypeVar

from sqlalchemy import Row, func, or_, select, text
from sqlalchemy import inspect as sa_inspect
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, aliased, selectinload

from backend import wards
from backend.models.alarms import Alarm, AlarmEvent, AlarmKind, AlarmState
from backend.models.robots import Robot, Transport
from backend.models.users import User
from backend.unit_of_work import savepoint

T = TypeVar("T")
SQLITE_BUSY_TIMEOUT_MS = 30_000  # the engine's own (backend.db: sqlite3 timeout=30)


class ReadTimedOut(Exception):
    """Storage did not answer a read within its timeout (a lock held by a stalled write)."""


@contextmanager
def _read_timeout(session: Session, timeout_ms: int) -> Iterator[None]:
    connection = session.connection()
    if connection.dialect.name == "postgresql":
        # Both: a read waits neither for a lock (lock_timeout) nor longer in total. SET LOCAL
        # inside a savepoint: undone with it, and the request's transaction stays usable.
        with savepoint(connection):
            connection.execute(text(f"SET LOCAL lock_timeout = {int(timeout_ms)}"))
            connection.execute(text(f"SET LOCAL statement_timeout = {int(timeout_ms)}"))
            yield
        return
    # SQLite (WAL): readers do not wait for the writer, except on a lock a checkpoint, a
    # recovery or a journal-mode change holds; a small busy timeout bounds that wait.
    connection.exec_driver_sql(f"PRAGMA busy_timeout = {int(timeout_ms)}")
    try:
        yield
    finally:
        connection.exec_driver_sql(f"PRAGMA busy_timeout = {SQLITE_BUSY_TIMEOUT_MS}")


def bounded_read(session: Session, timeout_ms: int, read: Callable[[], T]) -> T:
    """`read()` with storage given at most `timeout_ms` (statement and lock timeout on
    PostgreSQL, busy timeout on SQLite); raises ReadTimedOut when it does not answer."""
    try:
        with _read_timeout(session, timeout_ms):
            return read()
    except OperationalError as error:  # QueryCanceled, LockNotAvailable, database is locked
        raise ReadTimedOut(str(error).splitlines()[0]) from error


def visible_to(user: User):
    """Nurses see their own ward (every ward when they have none); others see all
    (the rule is backend.wards')."""
    return wards.alarms_visible(user)


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


def unresolved_rows(session: Session, user: User) -> list[dict]:
    """Every unresolved alarm the user may see, oldest first, as plain rows with the fields of
    AlarmOut (the nurse board's snapshot): one query of columns, no ORM objects, as hundreds
    of alarms may be open when a nurse opens the board."""
    acknowledger, resolver = aliased(User), aliased(User)
    query = (
        select(
            *Alarm.__table__.c,
            acknowledger.username.label("acknowledged_by"),
            resolver.username.label("resolved_by"),
            Transport.ended_at.label("transport_ended_at"),
        )
        .outerjoin(acknowledger, acknowledger.id == Alarm.acknowledged_by_id)
        .outerjoin(resolver, resolver.id == Alarm.resolved_by_id)
        .outerjoin(Transport, Transport.id == Alarm.transport_id)
        .where(visible_to(user), Alarm.state != AlarmState.RESOLVED)
        .order_by(Alarm.raised_at, Alarm.id)
    )
    return [dict(row) for row in session.execute(query).mappings()]


def get_visible(session: Session, user: User, alarm_id: int) -> Alarm | None:
    return session.scalars(select(Alarm).where(Alarm.id == alarm_id, visible_to(user))).first()


def events_of(session: Session, alarm_id: int) -> Sequence[AlarmEvent]:
    return session.scalars(
        select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
    ).all()


def active_transports(session: Session) -> Sequence[tuple[Transport, Robot]]:
    """Transports under way (not ended) with their robot."""
    return session.execute(
        select(Transport, Robot)
        .join(Robot, Robot.id == Transport.robot_id)
        .where(Transport.ended_at.is_(None))
    ).all()


def unresolved_outages(session: Session, kinds: Collection[AlarmKind]) -> Sequence[Row]:
    """Unresolved technical alarms of `kinds` (robot offline, stream stalled, patient not
    seen) with what says whether their cause ended: what the monitor checks every pass.

    Columns, not alarms: a robot that died mid-transport keeps its alarm open for hours, and
    loading each such alarm with its users and dispositions every second was most of the
    monitor's work with a few hundred of them. Rows: `alarm_id`, `kind`, `raised_at`,
    `last_seen_at` (the robot's), `transport_id`, `ended_at`, `last_patient_at`,
    `last_frame_at` (the transport's; None without one)."""
    return session.execute(
        select(
            Alarm.id.label("alarm_id"),
            Alarm.kind,
            Alarm.raised_at,
            Robot.last_seen_at,
            Transport.id.label("transport_id"),
            Transport.ended_at,
            Transport.last_patient_at,
            Transport.last_frame_at,
        )
        .join(Robot, Robot.id == Alarm.robot_id)
        .outerjoin(Transport, Transport.id == Alarm.transport_id)
        .where(Alarm.kind.in_(list(kinds)), Alarm.state != AlarmState.RESOLVED)
    ).all()


#: Transports per query when asking about many at once (SQLite's bound-parameter limit).
_IN_CHUNK = 500


def outages_with_an_alarm(
    session: Session, outages: Sequence[tuple[str, str, AlarmKind, datetime]]
) -> set[tuple[str, str, AlarmKind]]:
    """Of the outages (robot id, transport id, kind, silent since), those that already have
    their alarm: one of the kind on that transport that is unresolved or was raised since the
    silence began. One query per 500 transports, not one per transport and pass."""
    if not outages:
        return set()
    since = {(robot, key, kind): at for robot, key, kind, at in outages}
    keys = sorted({key for _, key, _, _ in outages})
    kinds = sorted({kind for _, _, kind, _ in outages})
    earliest = min(since.values())
    alarmed: set[tuple[str, str, AlarmKind]] = set()
    for start in range(0, len(keys), _IN_CHUNK):
        rows = session.execute(
            select(
                Alarm.robot_id, Alarm.transport_key, Alarm.kind, Alarm.resolved_at, Alarm.raised_at
            ).where(
                Alarm.transport_key.in_(keys[start : start + _IN_CHUNK]),
                Alarm.kind.in_(kinds),
                or_(Alarm.resolved_at.is_(None), Alarm.raised_at >= earliest),
            )
        )
        for robot_id, key, kind, resolved_at, raised_at in rows:
            outage = (robot_id, key, AlarmKind(kind))
            began = since.get(outage)
            if began is not None and (resolved_at is None or raised_at >= began):
                alarmed.add(outage)
    return alarmed


def load_for_board(session: Session, alarms: Sequence[Alarm]) -> None:
    """Load what the board needs of `alarms` and is not loaded yet (after a flush: defaults,
    transport, dispositions), in one query for all of them."""
    ids = [alarm.id for alarm in alarms if alarm.id is not None and sa_inspect(alarm).unloaded]
    for start in range(0, len(ids), _IN_CHUNK):
        session.scalars(
            select(Alarm)
            .where(Alarm.id.in_(ids[start : start + _IN_CHUNK]))
            .options(selectinload(Alarm.dispositions))
        ).unique().all()


def latest_of_kind(
    session: Session, robot_id: str, transport_id: str, kind: AlarmKind
) -> Alarm | None:
    return session.scalars(
        select(Alarm)
        .where(Alarm.robot_id == robot_id, Alarm.transport_key == transport_id, Alarm.kind == kind)
        .order_by(Alarm.raised_at.desc())
        .limit(1)
    ).first()


def latest_of_transport(session: Session, robot_id: str, transport_id: str) -> Alarm | None:
    """The transport's most recent alarm of any kind (unresolved first)."""
    return session.scalars(
        select(Alarm)
        .where(Alarm.robot_id == robot_id, Alarm.transport_key == transport_id)
        .order_by((Alarm.state == AlarmState.RESOLVED).asc(), Alarm.raised_at.desc())
        .limit(1)
    ).first()


#: What the monitor's due checks read of an alarm: candidates are read as these columns and
#: only the due ones loaded (`claim`); loading every open alarm with its users and
#: dispositions each second was most of a pass with a few hundred of them.
_DUE_COLUMNS = (
    Alarm.id,
    Alarm.state,
    Alarm.kind,
    Alarm.ward,
    Alarm.raised_at,
    Alarm.updated_at,
    Alarm.acknowledged_at,
    Alarm.escalated_at,
    Alarm.escalation_level,
    Alarm.escalated_to,
    Alarm.realarmed_at,
)


def open_emergencies(session: Session) -> Sequence[Row]:
    """Open Emergencies, as `_DUE_COLUMNS` rows."""
    return session.execute(
        select(*_DUE_COLUMNS).where(
            Alarm.state == AlarmState.OPEN, Alarm.kind == AlarmKind.EMERGENCY
        )
    ).all()


def missed_emergencies(session: Session) -> Sequence[Row]:
    """Missed Emergencies, as `_DUE_COLUMNS` rows."""
    return session.execute(
        select(*_DUE_COLUMNS).where(
            Alarm.state == AlarmState.MISSED, Alarm.kind == AlarmKind.EMERGENCY
        )
    ).all()


def acknowledged(session: Session) -> Sequence[Row]:
    """Acknowledged alarms, as `_DUE_COLUMNS` rows."""
    return session.execute(
        select(*_DUE_COLUMNS).where(Alarm.state == AlarmState.ACKNOWLEDGED)
    ).all()


def claim(session: Session, alarm_ids: Sequence[int]) -> Sequence[Alarm]:
    """Lock these alarms for a change, skipping rows another replica's monitor holds (SQLite,
    with its single writer, ignores the clause). Only due alarms are claimed, so the ingest
    writer is never held up by a monitor pass that changes nothing."""
    if not alarm_ids:
        return []
    query = select(Alarm).where(Alarm.id.in_(alarm_ids)).execution_options(populate_existing=True)
    return session.scalars(query.with_for_update(skip_locked=True, of=Alarm)).unique().all()


def audit_events(
    session: Session,
    user: User,
    alarm_id: int | None = None,
    actor: str | None = None,
    since: datetime | None = None,
    until: datetime | None = None,
    limit: int = 500,
) -> Sequence[AlarmEvent]:
    query = select(AlarmEvent).join(Alarm, Alarm.id == AlarmEvent.alarm_id).where(visible_to(user))
    if alarm_id is not None:
        query = query.where(AlarmEvent.alarm_id == alarm_id)
    if actor is not None:
        query = query.where(AlarmEvent.actor == actor)
    if since is not None:
        query = query.where(AlarmEvent.at >= since)
    if until is not None:
        query = query.where(AlarmEvent.at < until)
    return session.scalars(query.order_by(AlarmEvent.id.desc()).limit(limit)).all()


def viewer_names(session: Session, user_ids: Sequence[int]) -> dict[int, str]:
    """user id -> "name (role)" of people with a board open, for an escalation's audit entry."""
    if not user_ids:
        return {}
    rows = session.execute(
        select(User.id, User.username, User.role).where(User.id.in_(set(user_ids)))
    )
    return {uid: f"{name} ({role})" for uid, name, role in rows}


def unresolved_counts(session: Session) -> dict[AlarmKind, int]:
    """Unresolved alarms per kind (the /metrics gauge)."""
    return dict(
        session.execute(
            select(Alarm.kind, func.count())
            .where(Alarm.state != AlarmState.RESOLVED)
            .group_by(Alarm.kind)
        ).all()
    )


def unresolved_of_ward(session: Session, ward: str, kind: AlarmKind) -> Alarm | None:
    """The unresolved alarm of this kind about a ward rather than a robot."""
    return session.scalars(
        select(Alarm).where(
            Alarm.robot_id.is_(None),
            Alarm.transport_key == f"ward:{ward}",
            Alarm.kind == kind,
            Alarm.state != AlarmState.RESOLVED,
        )
    ).first()


def by_ids(session: Session, alarm_ids: Sequence[int]) -> Sequence[Alarm]:
    return session.scalars(select(Alarm).where(Alarm.id.in_(alarm_ids))).unique().all()
