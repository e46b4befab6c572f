import logging
from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, HTTPException, Path, Response, status

from backend.alarm_review import feedback
from backend.alarms import queries, service
from backend.alarms.schemas import AcknowledgeIn, AlarmEventOut, AlarmOut, ResolveIn
from backend.alarms.state import AlarmAction
from backend.deps import MAX_DB_INT, CurrentUser, DbId, SessionDep
from backend.ingest import stall_actions
from backend.models.alarms import Alarm, AlarmKind, AlarmState
from backend.realtime.hub import AlarmFilter
from backend.services import ServicesDep
from backend.unit_of_work import after_commit

log = logging.getLogger(__name__)
router = APIRouter(prefix="/api/alarms", tags=["alarms"])

#: A stored alarm's id, or a negative one: an alarm on the board not yet stored (storage
#: stalled), acknowledged and resolved all the same (backend.ingest.stall_actions).
ActionableId = Annotated[
    int,
    Path(
        ge=-MAX_DB_INT,
        le=MAX_DB_INT,
        description="the alarm's id; negative: a provisional alarm not yet stored",
    ),
]


def _act_on_provisional(
    services, session, user, alarm_id: int, action: AlarmAction, **fields
) -> AlarmOut:
    writer = services.writer
    if writer is None or writer.stall_actions is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"alarm {alarm_id} not found")
    try:
        card, refresh_card = stall_actions.act_on_provisional(
            writer.fail_open, writer.stall_actions, user, alarm_id, action, **fields
        )
    except stall_actions.NotActionable as error:
        raise HTTPException(error.status_code, error.message) from None

    async def show() -> None:  # on the board at once, before the alarm is stored
        refresh_card()
        await services.effects.publish_alarm(card)

    after_commit(session, show)
    return AlarmOut.model_validate(card)


def _get(session: SessionDep, user: CurrentUser, alarm_id: int) -> Alarm:
    alarm = queries.get_visible(session, user, alarm_id)
    if alarm is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"alarm {alarm_id} not found")
    return alarm


STALE_HEADER = "Vigil-Stale"


@router.get(
    "",
    responses={
        200: {
            "headers": {
                STALE_HEADER: {
                    "description": "present when storage did not answer within "
                    "alarm_list_timeout_ms: the list is the alarms this backend pushed to the "
                    "boards since it started (the last push of each; stored: false ones are "
                    "not yet stored), and says why",
                    "schema": {"type": "string"},
                }
            }
        }
    },
)
def list_alarms(
    session: SessionDep,
    user: CurrentUser,
    services: ServicesDep,
    response: Response,
    state: AlarmState | None = None,
    kind: AlarmKind | None = None,
    ward: str | None = None,
    robot_id: str | None = None,
    since: datetime | None = None,
    until: datetime | None = None,
) -> list[AlarmOut]:
    """Never waits behind a stalled write: a read storage does not answer within
    alarm_list_timeout_ms is answered from the hub's state, with the Vigil-Stale header."""
    timeout_ms = services.settings.alarm_list_timeout_ms
    try:
        alarms = queries.bounded_read(
            session,
            timeout_ms,
            lambda: queries.list_alarms(session, user, state, kind, ward, robot_id, since, until),
        )
    except queries.ReadTimedOut as error:
        where = AlarmFilter(state, kind, ward, robot_id, since, until)
        response.headers[STALE_HEADER] = (
            f"storage did not answer within {timeout_ms:g} ms: alarms pushed since this "
            "backend started, stored: false ones not yet stored"
        )
        log.warning("alarm list answered from the hub's state: %s", error)
        return [AlarmOut.model_validate(a) for a in services.hub.known_alarms(user, where)]
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
    alarm_id: ActionableId,
    session: SessionDep,
    user: CurrentUser,
    services: ServicesDep,
    body: AcknowledgeIn | None = None,
) -> AlarmOut:
    """A negative id: a provisional alarm (storage stalled); the acknowledgement is journalled,
    shown at once and applied once the alarm is stored."""
    comment = body.comment if body else None
    if alarm_id < 0:
        return _act_on_provisional(
            services, session, user, alarm_id, AlarmAction.ACKNOWLEDGE, comment=comment
        )
    alarm = _get(session, user, alarm_id)
    service.acknowledge(session, alarm, user, body.comment if body else None)
    session.flush()  # the unit of work commits, then pushes the alarm (alarms.service)
    return AlarmOut.model_validate(alarm)


@router.post("/{alarm_id}/resolve")
def resolve(
    alarm_id: ActionableId,
    body: ResolveIn,
    session: SessionDep,
    user: CurrentUser,
    services: ServicesDep,
) -> AlarmOut:
    """A negative id: a provisional alarm (storage stalled), as for acknowledge."""
    if alarm_id < 0:
        return _act_on_provisional(
            services,
            session,
            user,
            alarm_id,
            AlarmAction.RESOLVE,
            comment=body.comment,
            verdict=body.verdict,
            reason=body.reason,
        )  # noqa
    alarm = _get(session, user, alarm_id)
    service.resolve(session, alarm, user, body.verdict, body.reason, body.comment)
    feedback.propose_label_from_verdict(session, alarm, user.id)
    session.flush()  # the unit of work commits, then pushes the alarm (alarms.service)
    return AlarmOut.model_validate(alarm)
