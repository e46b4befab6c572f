"""Alarm lifecycle. Functions change rows and write the audit trail; the caller's unit of work
commits, then pushes every alarm changed here to the boards (`unit_of_work.publish_alarm`)."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.alarms import outbox, queries
from backend.alarms.schemas import alarm_json
from backend.alarms.state import ALARM, AlarmAction
from backend.models._types import utcnow
from backend.models.alarms import (
    PRIORITY_OF_KIND,
    TECHNICAL_KINDS,
    Alarm,
    AlarmEvent,
    AlarmKind,
    AlarmState,
    FalseAlarmReason,
    Verdict,
)
from backend.models.robots import Robot, Transport
from backend.models.users import User
from backend.unit_of_work import publish_alarm, tell_robot
from vigil import protocol


@dataclass(slots=True)
class DecisionEvidence:
    """What a robot's decision contributes to an alarm."""

    seq: int | None
    ts: float | None
    model_version: str | None = None
    threshold: float | None = None
    delay_ms: int | None = None
    video_id: int | None = None


def _record(
    session: Session,
    alarm: Alarm,
    action: AlarmAction,
    from_state: AlarmState | None,
    actor: str,
    user: User | None = None,
    comment: str | None = None,
) -> None:
    event = AlarmEvent(
        alarm_id=alarm.id,
        at=alarm.updated_at,
        actor_user_id=user.id if user else None,
        actor=actor,
        action=action.value,
        from_state=from_state,
        to_state=alarm.state,
        comment=comment,
    )
    session.add(event)
    outbox.enqueue(session, alarm, action, event)  # to the phones, in this same transaction
    publish(session, alarm)


def publish(session: Session, alarm: Alarm) -> None:
    """Push this alarm to the boards, as AlarmOut JSON, once the session's unit commits."""
    publish_alarm(session, alarm, board_json)


def board_json(session: Session, alarms: list[Alarm]) -> list[dict]:
    """The alarms as the boards receive them. A flush leaves a new alarm's defaults, its
    transport and its dispositions unloaded: one query loads them for all (the monitor raising
    or escalating hundreds in one pass made a query or two per alarm)."""
    queries.load_for_board(session, alarms)
    return [alarm_json(alarm) for alarm in alarms]


def find_unresolved(
    session: Session, robot_id: str, transport_id: str | None, kind: AlarmKind
) -> Alarm | None:
    return session.scalars(
        select(Alarm).where(
            Alarm.robot_id == robot_id,
            Alarm.transport_key == (transport_id or ""),
            Alarm.kind == kind,
            Alarm.state != AlarmState.RESOLVED,
        )
    ).first()


def fold_evidence(
    session: Session, alarm: Alarm, evidence: DecisionEvidence, now: datetime, push: bool = True
) -> Alarm:
    """A repeated decision updates the unresolved alarm instead of opening another; `push`:
    the boards get the updated alarm after the commit (the ingest path coalesces them)."""
    if push:
        publish(session, alarm)
    ALARM.target(alarm.state, AlarmAction.UPDATE)
    alarm.updated_at = now
    alarm.decision_count += 1
    if evidence.seq is not None:
        alarm.last_seq = max(alarm.last_seq or evidence.seq, evidence.seq)
        alarm.last_frame_ts = evidence.ts
    return alarm


def raise_or_update(
    session: Session,
    robot: Robot,
    transport: Transport | None,
    kind: AlarmKind,
    evidence: DecisionEvidence,
) -> tuple[Alarm, bool]:
    """Open an alarm for (transport, kind) or fold the evidence into the unresolved one.

    Returns the alarm and whether it is new.
    """
    transport_id = transport.id if transport else None
    alarm = find_unresolved(session, robot.id, transport_id, kind)
    if alarm is not None:
        return fold_evidence(session, alarm, evidence, utcnow()), False
    return open_alarm(session, robot, transport, kind, evidence), True


def open_alarm(
    session: Session,
    robot: Robot,
    transport: Transport | None,
    kind: AlarmKind,
    evidence: DecisionEvidence,
) -> Alarm:
    """Open an alarm for (transport, kind), for a caller that knows none is unresolved (the
    monitor, which asked for all of a pass's outages at once); the unique index refuses a
    second."""
    now = utcnow()
    transport_id = transport.id if transport else None
    alarm = Alarm(
        kind=kind,
        priority=PRIORITY_OF_KIND[kind],
        state=ALARM.initial,
        robot_id=robot.id,
        transport_id=transport_id,
        transport_key=transport_id or "",
        ward=robot.ward,
        patient=transport.patient if transport else None,
        location=transport.location if transport else None,
        raised_at=now,
        updated_at=now,
        video_id=evidence.video_id,
        first_seq=evidence.seq,
        last_seq=evidence.seq,
        first_frame_ts=evidence.ts,
        last_frame_ts=evidence.ts,
        decision_count=1,
        model_version=evidence.model_version,
        threshold=evidence.threshold,
        delay_ms=evidence.delay_ms,
    )
    session.add(alarm)
    session.flush()
    actor = "system" if kind in TECHNICAL_KINDS else f"robot:{robot.id}"
    _record(session, alarm, AlarmAction.RAISE, None, actor)
    return alarm


def _audited(prefix: str | None, text: str | None) -> str | None:
    """The audit comment, after what a deferred action says of itself (acting during a stall)."""
    if prefix is None:
        return text
    return f"{prefix}: {text}" if text else prefix


def acknowledge(
    session: Session,
    alarm: Alarm,
    user: User | None,
    comment: str | None = None,
    audit_prefix: str | None = None,
    via: str | None = None,
) -> Alarm:
    """`audit_prefix`: the audit comment starts with it (an acknowledgement made while the
    alarm was not yet stored: who, when, and when it was applied). `via` instead of a user:
    accepted by a clinician on a device of the alarm distribution ("Anna Berg on Anna's
    phone")."""
    if (user is None) == (via is None):
        raise ValueError("acknowledge: a user or a device, one of them")
    before = alarm.state
    ALARM.act(alarm, AlarmAction.ACKNOWLEDGE)
    alarm.updated_at = alarm.acknowledged_at = utcnow()
    if user is not None:
        alarm.acknowledged_by_id = user.id
        alarm.acknowledged_by_user = user
        actor = f"{user.role}:{user.username}"
    else:
        alarm.acknowledged_via = via
        actor = f"phone:{via}"
    _record(
        session,
        alarm,
        AlarmAction.ACKNOWLEDGE,
        before,
        actor,
        user,
        _audited(audit_prefix, comment),
    )
    if alarm.kind not in TECHNICAL_KINDS and alarm.robot_id:  # help is coming: tell the patient
        message = protocol.alarm_acknowledged(
            alarm.id,
            str(alarm.kind),
            alarm.transport_id,
            actor,
            alarm.acknowledged_at.timestamp(),
        )
        tell_robot(session, alarm.robot_id, message.model_dump_json())
    return alarm


def record_disposition(session: Session, alarm: Alarm, text: str) -> Alarm:
    """The alarm distribution reports what happened on a clinician's device: audited and
    shown on the board; the alarm's state does not change (an accept also acknowledges)."""
    before = alarm.state
    ALARM.act(alarm, AlarmAction.DISPOSITION)
    alarm.updated_at = utcnow()
    _record(session, alarm, AlarmAction.DISPOSITION, before, "alarm distribution", comment=text)
    return alarm


def raise_for_ward(
    session: Session, ward: str, kind: AlarmKind, details: dict, comment: str
) -> tuple[Alarm, bool]:
    """Open an alarm about no robot (a ward's: "alarm distribution down"), or update the
    unresolved one. Returns the alarm and whether it is new."""
    now = utcnow()
    alarm = unresolved_for_ward(session, ward, kind)
    if alarm is not None:
        if alarm.details != details:
            alarm.details = details
            alarm.updated_at = now
            publish(session, alarm)
        return alarm, False
    alarm = Alarm(
        kind=kind,
        priority=PRIORITY_OF_KIND[kind],
        robot_id=None,
        transport_id=None,
        transport_key=f"ward:{ward}",
        ward=ward,
        raised_at=now,
        updated_at=now,
        decision_count=1,
        details=details,
    )
    ALARM.start(alarm)
    session.add(alarm)
    session.flush()
    _record(session, alarm, AlarmAction.RAISE, None, "system", comment=comment)
    return alarm, True


def unresolved_for_ward(session: Session, ward: str, kind: AlarmKind) -> Alarm | None:
    return queries.unresolved_of_ward(session, ward, kind)


def resolve(
    session: Session,
    alarm: Alarm,
    user: User,
    verdict: Verdict,
    reason: FalseAlarmReason | None,
    comment: str | None,
    audit_prefix: str | None = None,
) -> Alarm:
    before = alarm.state
    ALARM.act(alarm, AlarmAction.RESOLVE)
    alarm.updated_at = alarm.resolved_at = utcnow()
    alarm.resolved_by_id = user.id
    alarm.resolved_by_user = user
    alarm.verdict = verdict
    alarm.reason = reason
    alarm.comment = comment
    note = verdict.value + (f" ({reason.value})" if reason else "")
    if comment:
        note += f": {comment}"
    _record(
        session,
        alarm,
        AlarmAction.RESOLVE,
        before,
        f"{user.role}:{user.username}",
        user,
        _audited(audit_prefix, note),
    )
    if alarm.kind not in TECHNICAL_KINDS:  # releases the robot's emergency stop
        message = protocol.alarm_resolved(
            alarm.id,
            str(alarm.kind),
            alarm.transport_id,
            f"{user.role}:{user.username}",
            alarm.resolved_at.timestamp(),
            verdict.value,
        )
        tell_robot(session, alarm.robot_id, message.model_dump_json())
    return alarm


def robot_reset(session: Session, robot_id: str, message: protocol.EmergencyReset) -> Alarm | None:
    """The robot's emergency stop was reset on the robot: written into the audit of the alarm
    it names (if that robot's), else of the transport's latest Emergency. None: no such alarm."""
    alarm = session.get(Alarm, message.alarm_id) if message.alarm_id is not None else None
    if alarm is None or alarm.robot_id != robot_id:
        alarm = queries.latest_of_kind(
            session, robot_id, message.transport_id or "", AlarmKind.EMERGENCY
        )
    if alarm is None:
        return None
    before = alarm.state
    ALARM.act(alarm, AlarmAction.ROBOT_RESET)
    alarm.updated_at = utcnow()
    at = datetime.fromtimestamp(message.ts, UTC).isoformat(timespec="seconds")
    _record(
        session,
        alarm,
        AlarmAction.ROBOT_RESET,
        before,
        f"robot:{robot_id}",
        comment=f"emergency stop reset on the robot ({message.by}) at {at}",
    )
    return alarm


#: How the audit and the board say what the robot did (nurse words).
ROBOT_STATE_WORDS = {
    "emergency_stop": "robot stopped, waiting for help",
    "paused": "robot paused",
    "transporting": "robot driving",
    "detection_degraded": "detection degraded, robot slowed or stopped",
}


def robot_behaviour(
    session: Session, robot_id: str, message: protocol.BehaviourChanged
) -> Alarm | None:
    """The robot reports what it does: written into the audit of the alarm it names (if that
    robot's), else of its transport's latest alarm (so "robot stopped 12:03:05" stands beside
    the Emergency), and shown on that alarm. None: no alarm to write it on."""
    alarm = session.get(Alarm, message.alarm_id) if message.alarm_id is not None else None
    if alarm is None or alarm.robot_id != robot_id:
        alarm = queries.latest_of_transport(session, robot_id, message.transport_id or "")
    if alarm is None:
        return None
    before = alarm.state
    ALARM.act(alarm, AlarmAction.ROBOT_BEHAVIOUR)
    since = datetime.fromtimestamp(message.since, UTC)
    alarm.robot_state = message.state.value
    alarm.robot_state_since = since
    alarm.updated_at = utcnow()
    words = ROBOT_STATE_WORDS[message.state.value]
    at = since.isoformat(timespec="seconds")
    _record(
        session,
        alarm,
        AlarmAction.ROBOT_BEHAVIOUR,
        before,
        f"robot:{robot_id}",
        comment=f"{words} ({message.state.value}) at {at}: {message.reason}",
    )
    return alarm


def clear(session: Session, alarm: Alarm, now: datetime, comment: str) -> Alarm:
    """The system resolves a technical alarm whose cause ended (no verdict, no user)."""
    before = alarm.state
    ALARM.act(alarm, AlarmAction.CLEAR)
    alarm.updated_at = alarm.resolved_at = now
    _record(session, alarm, AlarmAction.CLEAR, before, "system", comment=comment)
    return alarm


def escalate(
    session: Session, alarm: Alarm, now: datetime, notified: list[str] | None = None
) -> Alarm:
    """Raise the escalation level: the alarm is announced again, with its tone, on every board
    that shows its ward. The audit entry names who had such a board open (`notified`)."""
    before = alarm.state
    ALARM.act(alarm, AlarmAction.ESCALATE)
    alarm.escalation_level += 1
    alarm.escalated_at = alarm.updated_at = now
    audience = (
        f"signed in: {', '.join(sorted(set(notified)))}"
        if notified
        else "nobody had a board of this ward open"
    )
    _record(
        session,
        alarm,
        AlarmAction.ESCALATE,
        before,
        "system",
        comment=f"not acknowledged: escalated to level {alarm.escalation_level}; announced "
        f"again on every board showing ward {alarm.ward} ({audience})",
    )
    return alarm


def miss(session: Session, alarm: Alarm, now: datetime) -> Alarm:
    """The last escalation level went unanswered too: "missed: needs review" (latched)."""
    before = alarm.state
    ALARM.act(alarm, AlarmAction.MISS)
    # The further responders' wait counts from the miss.
    alarm.escalated_at = alarm.updated_at = now
    _record(
        session,
        alarm,
        AlarmAction.MISS,
        before,
        "system",
        comment=f"not acknowledged after the last escalation level "
        f"({alarm.escalation_level}): missed, needs review",
    )
    return alarm


def escalate_missed(session: Session, alarm: Alarm, now: datetime, responder: str) -> Alarm:
    """A missed Emergency still unanswered goes on to the ward's next responder (charge nurse,
    then the rapid-response team): it stays missed, and the audit says who was called."""
    before = alarm.state
    ALARM.act(alarm, AlarmAction.ESCALATE)
    unanswered = int((now - alarm.raised_at).total_seconds() // 60)
    alarm.escalation_level += 1
    alarm.escalated_at = alarm.updated_at = now
    alarm.escalated_to = responder
    _record(
        session,
        alarm,
        AlarmAction.ESCALATE,
        before,
        "system",
        comment=f"missed, unanswered {unanswered} min: escalated to {responder}",
    )
    return alarm


def realarm(session: Session, alarm: Alarm, now: datetime) -> Alarm:
    before = alarm.state
    ALARM.act(alarm, AlarmAction.REALARM)
    alarm.realarmed_at = alarm.updated_at = now
    _record(
        session,
        alarm,
        AlarmAction.REALARM,
        before,
        "system",
        comment="acknowledged but not resolved in time",
    )
    return alarm
