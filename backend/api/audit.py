from datetime import datetime

from fastapi import APIRouter, Query

from backend.alarms import queries
from backend.alarms.schemas import AlarmEventOut
from backend.deps import MAX_DB_INT, CurrentUser, SessionDep

router = APIRouter(prefix="/api/audit", tags=["audit"])


@router.get("")
def audit_trail(
    session: SessionDep,
    user: CurrentUser,
    alarm_id: int | None = Query(default=None, ge=1, le=MAX_DB_INT),
    actor: str | None = Query(default=None, max_length=128, description="e.g. nurse:alice"),
    since: datetime | None = None,
    until: datetime | None = None,
    limit: int = Query(default=500, ge=1, le=5000),
) -> list[AlarmEventOut]:
    """Every alarm transition (who, when, from, to, comment), newest first."""
    events = queries.audit_events(session, user, alarm_id, actor, since, until, limit)
    return [AlarmEventOut.model_validate(e) for e in events]
