"""Nurse review of alarms: replay, history, alarm-fatigue statistics, the label review queue."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from fastapi import APIRouter, HTTPException, Query, Response, status
from pydantic_core import to_json

from backend import wards
from backend.alarm_review import feedback, queries
from backend.alarm_review.fatigue import fatigue_stats, shift_of
from backend.alarm_review.handover import handover, to_csv
from backend.alarm_review.schemas import (
    AlarmPageOut,
    AlarmReplayOut,
    FatigueOut,
    HandoverOut,
    ReviewItemOut,
)
from backend.alarms import queries as alarm_queries
from backend.alarms.schemas import AlarmOut
from backend.api.downloads import attachment
from backend.deps import CurrentUser, SessionDep
from backend.models import Video
from backend.models._types import utcnow
from backend.models.alarms import AlarmKind, Verdict
from backend.models.users import User
from backend.storage.frame_reads import json_frames

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


@router.get("/alarms/{alarm_id}/replay", response_model=AlarmReplayOut)
def alarm_replay(
    alarm_id: int,
    session: SessionDep,
    user: CurrentUser,
    before_s: float = Query(default=5.0, ge=0, le=60, description="seconds before the alarm"),
    after_s: float = Query(default=5.0, ge=0, le=60, description="seconds after the alarm"),
) -> Response:
    # AlarmReplayOut, encoded without a pydantic model per frame (backend.storage.frame_reads:
    # 600 frames and more; serialisation was most of the time of a replay).
    alarm = alarm_queries.get_visible(session, user, alarm_id)
    if alarm is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"alarm {alarm_id} not found")
    frames = json_frames(queries.frames_around(session, alarm, before_s, after_s))
    for frame in frames:
        frame["scores"] = frame["scores"] or {}
    video = session.get(Video, alarm.video_id) if alarm.video_id is not None else None
    payload = {
        "alarm": AlarmOut.model_validate(alarm).model_dump(mode="json"),
        "before_s": before_s,
        "after_s": after_s,
        "generated": bool(video and video.generated),
        "frames": frames,
    }
    return Response(to_json(payload), media_type="application/json")


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
    missed = queries.ever_missed(session, [a.id for a in alarms])
    return FatigueOut(
        since=since, until=until, **fatigue_stats(alarms, min(until, utcnow()), missed)
    )


def _handover(
    session: SessionDep, user: User, since: datetime | None, ward: str | None
) -> tuple[HandoverOut, dict]:
    now = utcnow()
    shift_start, shift_name = shift_of(now)
    since = since or shift_start
    if since.tzinfo is None:  # a time without a zone is UTC, as every time the API sends
        since = since.replace(tzinfo=UTC)
    if since >= now:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, "since must be in the past")
    if now - since > timedelta(days=MAX_FATIGUE_DAYS):
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_CONTENT, f"at most {MAX_FATIGUE_DAYS} days at once"
        )
    ward = _ward_of(user, ward)
    alarms = queries.handover_alarms(session, since, now, ward)
    missed = queries.ever_missed(session, [a.id for a in alarms])
    report = handover(alarms, missed, since, now)
    out = HandoverOut(
        since=since,
        until=now,
        shift=shift_name if since == shift_start else None,
        ward=ward,
        counts=report["counts"],
        per_robot=report["per_robot"],
        fatigue=report["fatigue"],
        alarms=[
            {
                "section": r["section"],
                "was_missed": r["was_missed"],
                "alarm": AlarmOut.model_validate(r["alarm"]),
            }
            for r in report["alarms"]
        ],
    )
    return out, report


@router.get("/handover")
def shift_handover(
    session: SessionDep,
    user: CurrentUser,
    since: datetime | None = Query(default=None, description="default: the current shift's start"),
    ward: str | None = None,
) -> HandoverOut:
    """The shift so far: open, missed, acknowledged-unresolved and escalated alarms, per robot,
    with the shift's fatigue figures."""
    return _handover(session, user, since, ward)[0]


@router.get(
    "/handover.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}, "description": "the handover as CSV"}},
)
def shift_handover_csv(
    session: SessionDep,
    user: CurrentUser,
    since: datetime | None = Query(default=None, description="default: the current shift's start"),
    ward: str | None = None,
) -> Response:
    out, report = _handover(session, user, since, ward)
    name = f"handover-{out.ward or 'all-wards'}-{out.until:%Y%m%d-%H%M}.csv"
    return Response(
        to_csv(report, out.since, out.until, out.ward),
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": attachment(name)},
    )


@router.get("/review-queue")
def review_queue(
    session: SessionDep, user: CurrentUser, limit: int = Query(default=100, ge=1, le=500)
) -> list[ReviewItemOut]:
    """Pending labels for annotators to review; alarms nurses rejected as false come first."""
    return [ReviewItemOut.model_validate(s) for s in feedback.review_queue(session, limit)]
