"""Labelling API: segments, their status, review and history, and the review queue."""

from __future__ import annotations

from fastapi import APIRouter, Query, Response, status

from backend.alarm_review.feedback import placeholder_name
from backend.deps import CurrentUser, DbId, SessionDep
from backend.labelling import segments
from backend.labelling.errors import LabellingError
from backend.labelling.queries import (
    user_by_name,
    usernames,
    video_modes,
    video_segments,
)
from backend.labelling.review import review_queue
from backend.labelling.schemas import (
    QueueItemOut,
    ReviewIn,
    SegmentEventOut,
    SegmentIn,
    SegmentOut,
    SegmentPatch,
    StatusAction,
    SubmitAllOut,
)
from backend.labelling.taxonomy import load_taxonomy
from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus

router = APIRouter(prefix="/api/labelling", tags=["labelling"])


# -- segments -------------------------------------------------------------------------------


def _segment_outs(session, items: list[AnnotationSegment]) -> list[SegmentOut]:
    taxonomy = load_taxonomy(session)
    names = usernames(session, [s.annotator_id for s in items] + [s.reviewer_id for s in items])
    modes = video_modes(session, {s.video_id for s in items})
    out = []
    for s in items:
        label = taxonomy.get(s.label_key)
        item = SegmentOut.model_validate(s)
        item.label_name = label.name if label else placeholder_name(s.label_key)
        item.decision = label.decision(modes[s.video_id]) if label else None
        item.annotator = names.get(s.annotator_id)
        item.reviewer = names.get(s.reviewer_id)
        out.append(item)
    return out


@router.get("/videos/{video_id}/segments")
def list_segments(
    video_id: DbId,
    session: SessionDep,
    user: CurrentUser,
    annotator: str | None = None,
    status_: list[SegmentStatus] | None = Query(default=None, alias="status"),
) -> list[SegmentOut]:
    segments.get_video(session, video_id)
    items = video_segments(
        session, video_id, status_ or [s for s in SegmentStatus if s != SegmentStatus.DELETED]
    )
    if annotator is not None:
        owner = user_by_name(session, annotator)
        items = [s for s in items if owner is not None and s.annotator_id == owner.id]
    return _segment_outs(session, items)


@router.post("/videos/{video_id}/segments", status_code=status.HTTP_201_CREATED)
def create_segment(
    video_id: DbId, body: SegmentIn, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    video = segments.get_video(session, video_id)
    segment = segments.create_segment(
        session,
        video,
        segments.SegmentDraft(body.first_frame, body.last_frame, body.label_key),
        user,
        source=SegmentSource(body.source),
    )
    return _segment_outs(session, [segment])[0]


@router.patch("/segments/{segment_id}")
def update_segment(
    segment_id: DbId, body: SegmentPatch, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.update_segment(session, segment, user, **body.model_dump(exclude_unset=True))
    return _segment_outs(session, [segment])[0]


@router.delete("/segments/{segment_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_segment(segment_id: DbId, session: SessionDep, user: CurrentUser) -> Response:
    segments.delete_segment(session, segments.get_segment(session, segment_id), user)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/segments/{segment_id}/status")
def change_status(
    segment_id: DbId, body: StatusAction, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.transition(session, segment, user, body.action, body.comment)
    return _segment_outs(session, [segment])[0]


@router.post("/videos/{video_id}/submit")
def submit_drafts(video_id: DbId, session: SessionDep, user: CurrentUser) -> SubmitAllOut:
    """Submit every draft (and rejected, revised) segment of the caller on this video."""
    segments.get_video(session, video_id)
    mine = [
        s
        for s in video_segments(session, video_id, [SegmentStatus.DRAFT, SegmentStatus.REJECTED])
        if s.annotator_id == user.id
    ]
    if not mine:
        raise LabellingError("segments: you have no draft segments on this video to submit")
    for segment in mine:
        segments.transition(session, segment, user, "submit", None)
    return SubmitAllOut(submitted=[s.id for s in mine])


@router.post("/segments/{segment_id}/review")
def review_segment(
    segment_id: DbId, body: ReviewIn, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.transition(session, segment, user, body.decision, body.comment)
    return _segment_outs(session, [segment])[0]


@router.get("/segments/{segment_id}/history")
def segment_history(
    segment_id: DbId, session: SessionDep, user: CurrentUser
) -> list[SegmentEventOut]:
    segments.get_segment(session, segment_id)
    events = segments.history(session, segment_id)
    names = usernames(session, [e.actor_id for e in events])
    return [
        SegmentEventOut(
            at=e.at,
            actor=names.get(e.actor_id) if e.actor_id else "system",
            action=e.action,
            snapshot=e.snapshot,
            comment=e.comment,
        )
        for e in events
    ]


@router.get("/review-queue")
def get_review_queue(
    session: SessionDep, user: CurrentUser, limit: int = Query(default=200, ge=1, le=1000)
) -> list[QueueItemOut]:
    items = review_queue(session, limit)
    outs = _segment_outs(session, [it.segment for it in items])
    return [
        QueueItemOut(segment=o, video_name=it.video.name, rank=it.rank, reason=it.reason)
        for o, it in zip(outs, items, strict=True)
    ]
