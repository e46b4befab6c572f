"""Nurse review of alarms: replay, history, alarm-fatigue statistics, the label review queue."""

from __future__ import annotations

from datetime import datetime, timedelta

from fastapi import APIRouter, HTTPException, Query, status

from backend import wards
from backend.alarm_review import feedback, queries
from backend.alarm_review.fatigue import fatigue_stats
from backend.alarm_review.schemas import (
    AlarmPageOut,
    AlarmReplayOut,
    FatigueOut,
    ReplayFrameOut,
    ReviewItemOut,
)
from backend.alarms import queries as alarm_queries
from backend.alarms.schemas import AlarmOut
from backend.deps import CurrentUser, SessionDep
from backend.models import Frame, Video
from backend.models._types import utcnow
from backend.models.alarms import AlarmKind, Verdict
from backend.models.users import User
from vigil.skeleton import decode_keypoints, depth_to_json

router = APIRouter(prefix="/api", tags=["alarm review"])

MAX_FATIGUE_DAYS = 92


def _ward_of(user: User, ward: str | None) -> str | None:
    """A nurse with a ward sees only that ward, whatever the filter asks."""
    confined = wards.ward_of(user)
    if confined is not None:
        if ward and ward != confined:
            raise HTTPException(status.HTTP_403_FORBIDDEN, f"ward {ward} is not your ward")
        return confined
    return ward


def _replay_frame(frame: Frame) -> ReplayFrameOut:
    depth = depth_to_json(frame.depth)
    return ReplayFrameOut(
        seq=frame.seq,
        index=frame.index,
        ts=frame.ts,
        keypoints=decode_keypoints(frame.keypoints).tolist(),
        depth=depth,
        decision=frame.decision,
        scores=frame.scores or {},
        model_version=frame.model_version,
    )


@router.get("/alarms/{alarm_id}/replay")
def alarm_replay(
    alarm_id: int,
    session: SessionDep,
    user: CurrentUser,
    before_s: float = Query(default=5.0, ge=0, le=60, description="seconds before the alarm"),
    after_s: float = Query(default=5.0, ge=0, le=60, description="seconds after the alarm"),
) -> AlarmReplayOut:
    alarm = alarm_queries.get_visible(session, user, alarm_id)
    if alarm is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"alarm {alarm_id} not found")
    frames = queries.frames_around(session, alarm, before_s, after_s)
    video = session.get(Video, alarm.video_id) if alarm.video_id is not None else None
    return AlarmReplayOut(
        alarm=AlarmOut.model_validate(alarm),
        before_s=before_s,
        after_s=after_s,
        generated=bool(video and video.generated),
        frames=[_replay_frame(f) for f in frames],
    )


@router.get("/alarm-history")
def alarm_history(
    session: SessionDep,
    user: CurrentUser,
    ward: str | None = None,
    robot_id: str | None = None,
    kind: AlarmKind | None = None,
    verdict: Verdict | None = None,
    model_version: str | None = None,
    since: datetime | None = None,
    until: datetime | None = None,
    limit: int = Query(default=50, ge=1, le=500),
    offset: int = Query(default=0, ge=0),
) -> AlarmPageOut:
    if since and until and until <= since:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "until must be after since")
    filters = queries.HistoryFilter(
        _ward_of(user, ward), robot_id, kind, verdict, model_version, since, until
    )
    total, alarms = queries.alarm_history(session, filters, limit, offset)
    return AlarmPageOut(total=total, items=[AlarmOut.model_validate(a) for a in alarms])


@router.get("/alarm-fatigue")
def alarm_fatigue(
    session: SessionDep,
    user: CurrentUser,
    since: datetime | None = Query(default=None, description="default: 7 days before until"),
    until: datetime | None = Query(default=None, description="default: now"),
    ward: str | None = None,
) -> FatigueOut:
    until = until or utcnow()
    since = since or until - timedelta(days=7)
    if until <= since:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "until must be after since")
    if until - since > timedelta(days=MAX_FATIGUE_DAYS):
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_CONTENT, f"at most {MAX_FATIGUE_DAYS} days at once"
        )
    alarms = queries.alarms_between(session, since, until, _ward_of(user, ward))
    return FatigueOut(since=since, until=until, **fatigue_stats(alarms, min(until, utcnow())))


@router.get("/review-queue")
def review_queue(
    session: SessionDep, user: CurrentUser, limit: int = Query(default=100, ge=1, le=500)
) -> list[ReviewItemOut]:
    """Pending labels for annotators to review; alarms nurses rejected as false come first."""
    return [ReviewItemOut.model_validate(s) for s in feedback.review_queue(session, limit)]
