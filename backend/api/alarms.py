from datetime import datetime

from fastapi import APIRouter, HTTPException, status

from backend.alarm_review import feedback
from backend.alarms import queries, service
from backend.alarms.schemas import AcknowledgeIn, AlarmEventOut, AlarmOut, ResolveIn
from backend.deps import CurrentUser, DbId, SessionDep
from backend.models.alarms import Alarm, AlarmKind, AlarmState

router = APIRouter(prefix="/api/alarms", tags=["alarms"])


def _get(session: SessionDep, user: CurrentUser, alarm_id: int) -> Alarm:
    alarm = queries.get_visible(session, user, alarm_id)
    if alarm is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"alarm {alarm_id} not found")
    return alarm


@router.get("")
def list_alarms(
    session: SessionDep,
    user: CurrentUser,
    state: AlarmState | None = None,
    kind: AlarmKind | None = None,
    ward: str | None = None,
    robot_id: str | None = None,
    since: datetime | None = None,
    until: datetime | None = None,
) -> list[AlarmOut]:
    alarms = queries.list_alarms(session, user, state, kind, ward, robot_id, since, until)
    return [AlarmOut.model_validate(a) for a in alarms]


@router.get("/{alarm_id}")
def get_alarm(alarm_id: DbId, session: SessionDep, user: CurrentUser) -> AlarmOut:
    return AlarmOut.model_validate(_get(session, user, alarm_id))


@router.get("/{alarm_id}/events")
def alarm_events(alarm_id: DbId, session: SessionDep, user: CurrentUser) -> list[AlarmEventOut]:
    _get(session, user, alarm_id)
    return [AlarmEventOut.model_validate(e) for e in queries.events_of(session, alarm_id)]


@router.post("/{alarm_id}/acknowledge")
def acknowledge(
    alarm_id: DbId,
    session: SessionDep,
    user: CurrentUser,
    body: AcknowledgeIn | None = None,
) -> AlarmOut:
    alarm = _get(session, user, alarm_id)
    service.acknowledge(session, alarm, user, body.comment if body else None)
    session.flush()  # the unit of work commits, then pushes the alarm (alarms.service)
    return AlarmOut.model_validate(alarm)


@router.post("/{alarm_id}/resolve")
def resolve(
    alarm_id: DbId,
    body: ResolveIn,
    session: SessionDep,
    user: CurrentUser,
) -> AlarmOut:
    alarm = _get(session, user, alarm_id)
    service.resolve(session, alarm, user, body.verdict, body.reason, body.comment)
    feedback.propose_label_from_verdict(session, alarm, user.id)
    session.flush()  # the unit of work commits, then pushes the alarm (alarms.service)
    return AlarmOut.model_validate(alarm)
