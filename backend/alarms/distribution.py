"""What the alarm distribution does to alarms: dispositions from clinicians' devices (an
accept acknowledges), and the technical alarm "alarm distribution down" of each ward whose
Alert Manager cannot be reached (raised and cleared by the sender's hooks)."""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy.orm import Session

from backend.alarms import service
from backend.alarms.state import ALARM, AlarmAction
from backend.distribution import queries as outbox_queries
from backend.distribution.hl7_messages import AlertStatus, Disposition, MessageError
from backend.distribution.routing import Destination, Routing
from backend.models.alarms import Alarm, AlarmDisposition, AlarmKind

DOWN = AlarmKind.ALARM_DISTRIBUTION_DOWN
_WORDS = {
    Disposition.DELIVERED: "delivered to",
    Disposition.READ: "read on",
    Disposition.ACCEPTED: "accepted on",
    Disposition.REJECTED: "rejected on",
}


def apply_status(session: Session, status: AlertStatus) -> str:
    """Record one ORA^R41 on the alarm whose ORU^R40 it answers; MessageError (answered AE)
    when it answers no message Vigil sent."""
    message = outbox_queries.by_control_id(session, status.answers)
    if message is None:
        raise MessageError(f"MSA-2: Vigil sent no ORU^R40 with control id {status.answers!r}")
    if outbox_queries.disposition_recorded(session, status.control_id):
        return f"status {status.control_id} already recorded"
    alarm = session.get(Alarm, message.alarm_id)
    if alarm is None:
        raise MessageError(f"OBR-2: alarm {status.alert!r} no longer exists")
    session.add(
        AlarmDisposition(
            alarm_id=alarm.id,
            message_id=message.id,
            control_id=status.control_id,
            disposition=status.disposition.value,
            clinician_id=status.clinician_id[:64],
            clinician=status.clinician[:128],
            device=status.device[:128],
            at=status.at,
        )
    )
    session.flush()
    session.expire(alarm, ["dispositions"])
    at = status.at.astimezone(UTC).strftime("%H:%M:%S")
    text = f"{_WORDS[status.disposition]} {status.device} ({status.clinician}) at {at} UTC"
    service.record_disposition(session, alarm, text)
    if (
        status.disposition is Disposition.ACCEPTED
        and alarm.state in ALARM.actions[AlarmAction.ACKNOWLEDGE]
    ):
        service.acknowledge(
            session,
            alarm,
            None,
            comment=f"accepted on {status.device}",
            via=f"{status.clinician} on {status.device}",
        )
    return f"alarm {alarm.id}: {text}"


def _wards(session: Session, routing: Routing, destination: Destination) -> list[str]:
    return routing.wards_of(destination, outbox_queries.known_wards(session))


def distribution_down(
    session: Session, routing: Routing, destination: Destination, error: str, since: datetime
) -> list[Alarm]:
    """Each ward the Alert Manager serves gets "alarm distribution down" on its board."""
    pending = outbox_queries.pending_by_ward(session, str(destination))
    raised = []
    for ward in _wards(session, routing, destination):
        details = {
            "destination": str(destination),
            "since": since.isoformat(),
            "error": error,
            "pending_messages": pending.get(ward, 0),
            "summary": f"alarms are not reaching phones and pagers: Alert Manager {destination} "
            f"unreachable since {since.astimezone(UTC):%H:%M:%S} UTC ({error})",
        }
        alarm, _ = service.raise_for_ward(session, ward, DOWN, details, details["summary"])
        raised.append(alarm)
    return raised


def distribution_up(
    session: Session, routing: Routing, destination: Destination, down_since: datetime | None
) -> list[Alarm]:
    now = datetime.now(UTC)
    took = f" after {int((now - down_since).total_seconds())} s" if down_since else ""
    cleared = []
    for ward in _wards(session, routing, destination):
        alarm = service.unresolved_for_ward(session, ward, DOWN)
        if alarm is not None:
            service.clear(
                session,
                alarm,
                now,
                f"Alert Manager {destination} reachable again{took}; queued alarm "
                "messages are being delivered",
            )
            cleared.append(alarm)
    return cleared
