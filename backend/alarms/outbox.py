"""Each alarm change, queued for the alarm distribution in the change's own transaction: the
change and what its ORU^R40 reports are stored together or not at all (the sender in
`backend.distribution.sender` builds and delivers the message; a restart loses none). The
message itself is built by the sender, not here: building and validating it with hl7apy takes
tens of milliseconds, which inside the frame writer's transaction held the write lock for
seconds when a hundred robots raised Emergencies at once."""

from __future__ import annotations

from sqlalchemy.orm import Session

from backend.alarms.state import AlarmAction
from backend.distribution import routing as routing_
from backend.distribution.hl7_messages import (
    AlertReport,
    Change,
    new_control_id,
)
from backend.distribution.state import MESSAGE
from backend.models.alarms import TECHNICAL_KINDS, Alarm, AlarmEvent, AlarmKind, AlarmMessage
from backend.unit_of_work import of as unit_of

#: The alarm changes a phone hears of (an update folding in another decision, the robot's
#: behaviour and the phone's own dispositions are not changes of the alert).
CHANGE_OF_ACTION = {
    AlarmAction.RAISE: Change.RAISED,
    AlarmAction.ESCALATE: Change.ESCALATED,
    AlarmAction.MISS: Change.MISSED,
    AlarmAction.REALARM: Change.REALARMED,
    AlarmAction.ACKNOWLEDGE: Change.ACKNOWLEDGED,
    AlarmAction.RESOLVE: Change.RESOLVED,
    AlarmAction.CLEAR: Change.CLEARED,
}

#: What a phone says of each kind (nurse words).
KIND_WORDS = {
    AlarmKind.EMERGENCY: "Patient emergency (fall suspected)",
    AlarmKind.PAUSE: "Transport paused for patient safety",
    AlarmKind.ROBOT_OFFLINE: "Robot offline",
    AlarmKind.STREAM_STALLED: "Robot camera stream stalled",
    AlarmKind.DETECTION_DEGRADED: "Fall detection degraded",
    AlarmKind.STORAGE_STALLED: "Vigil storage stalled",
    AlarmKind.PATIENT_NOT_SEEN: "Robot does not see its patient",
    AlarmKind.ALARM_DISTRIBUTION_DOWN: "Alarm distribution down",
}


def _who(actor: str) -> str:
    return actor.split(":", 1)[1] if ":" in actor else actor


def phone_text(alarm: Alarm, change: Change, event: AlarmEvent) -> str:
    """One line a phone or pager shows."""
    where = ", ".join(
        part
        for part in (
            f"patient {alarm.patient}" if alarm.patient else None,
            alarm.location,
            f"robot {alarm.robot_id}" if alarm.robot_id else None,
            f"ward {alarm.ward}",
        )
        if part
    )
    text = f"{KIND_WORDS.get(AlarmKind(alarm.kind), str(alarm.kind))}: {where}"
    if change in (Change.ESCALATED, Change.REALARMED):
        text += f" (not acknowledged: level {alarm.escalation_level})"
    elif change is Change.MISSED:
        text += " (MISSED: nobody acknowledged)"
    elif change is Change.ACKNOWLEDGED:
        text += f" (acknowledged by {_who(event.actor)})"
    elif change is Change.RESOLVED:
        text += f" (resolved by {_who(event.actor)})"
    elif change is Change.CLEARED:
        text += " (cause ended)"
    if alarm.escalated_to and change in (Change.ESCALATED, Change.MISSED):
        text += f" -> {alarm.escalated_to}"
    return text


def report_of(alarm: Alarm, change: Change, event: AlarmEvent, control_id: str) -> AlertReport:
    return AlertReport(
        control_id=control_id,
        alarm_id=alarm.id,
        change=change,
        kind=str(alarm.kind),
        kind_text=KIND_WORDS.get(AlarmKind(alarm.kind), str(alarm.kind)),
        priority=str(alarm.priority),
        technical=alarm.kind in TECHNICAL_KINDS,
        ward=alarm.ward,
        robot_id=alarm.robot_id,
        patient=alarm.patient,
        location=alarm.location,
        raised_at=alarm.raised_at,
        at=event.at,
        text=phone_text(alarm, change, event),
        escalation_level=alarm.escalation_level,
        escalated_to=alarm.escalated_to,
        by=_who(event.actor) if change in (Change.ACKNOWLEDGED, Change.RESOLVED) else None,
    )


def enqueue(
    session: Session, alarm: Alarm, action: AlarmAction, event: AlarmEvent
) -> AlarmMessage | None:
    """Queue the ORU^R40 of this change, if the alarm's ward has an Alert Manager."""
    routing = routing_.of(session)
    change = CHANGE_OF_ACTION.get(action)
    if routing is None or change is None or alarm.kind == AlarmKind.ALARM_DISTRIBUTION_DOWN:
        return None
    destination = routing.destination_for(alarm.ward)
    if destination is None:
        return None
    session.flush()  # the event's id
    control_id = new_control_id()
    message = AlarmMessage(
        alarm_id=alarm.id,
        event_id=event.id,
        change=change.value,
        ward=alarm.ward,
        destination=str(destination),
        control_id=control_id,
        facility=routing.facility,
        report=report_of(alarm, change, event, control_id).to_json(),
        created_at=event.at,
    )
    MESSAGE.start(message)
    session.add(message)
    unit = unit_of(session)
    wake = routing_.waker(session)
    if unit is not None and wake is not None:
        unit.after_commit(wake)
    return message
