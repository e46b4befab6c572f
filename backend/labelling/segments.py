"""Annotation segments: create, edit, delete and move through review, each step in the history.

The caller's request commits; these functions only add and flush.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.labelling.errors import Forbidden, LabellingError, NotFound
from backend.labelling.status import EDITABLE, REVIEW_ACTIONS, SEGMENT, next_status
from backend.labelling.taxonomy import load_taxonomy, require
from backend.models._types import utcnow
from backend.models.annotations import (
    AnnotationSegment,
    SegmentEvent,
    SegmentSource,
    SegmentStatus,
)
from backend.models.users import Role, User
from backend.models.videos import Video


@dataclass(frozen=True, slots=True)
class SegmentDraft:
    first_frame: int
    last_frame: int
    label_key: str


def snapshot(segment: AnnotationSegment) -> dict:
    return {
        "first_frame": segment.first_frame,
        "last_frame": segment.last_frame,
        "label_key": segment.label_key,
        "status": str(segment.status),
        "source": str(segment.source),
        "annotator_id": segment.annotator_id,
        "reviewer_id": segment.reviewer_id,
        "review_comment": segment.review_comment,
    }


def record(
    session: Session, segment: AnnotationSegment, actor: User | None, action: str, comment=None
) -> None:
    session.flush()
    session.add(
        SegmentEvent(
            segment_id=segment.id,
            actor_id=actor.id if actor else None,
            action=action,
            snapshot=snapshot(segment),
            comment=comment,
        )
    )


def validate_frames(video: Video, first_frame: int, last_frame: int) -> None:
    if first_frame < 0:
        raise LabellingError(f"first_frame: {first_frame} is negative")
    if last_frame < first_frame:
        raise LabellingError(f"last_frame: {last_frame} is before first_frame {first_frame}")
    if last_frame >= video.frame_count:
        raise LabellingError(
            f"last_frame: {last_frame} is past the video's last frame {video.frame_count - 1}"
        )


def get_video(session: Session, video_id: int) -> Video:
    video = session.get(Video, video_id)
    if video is None:
        raise NotFound(f"video {video_id} not found")
    return video


def get_segment(session: Session, segment_id: int) -> AnnotationSegment:
    segment = session.get(AnnotationSegment, segment_id)
    if segment is None:
        raise NotFound(f"segment {segment_id} not found")
    return segment


def create_segment(
    session: Session,
    video: Video,
    draft: SegmentDraft,
    actor: User | None,
    *,
    source: SegmentSource = SegmentSource.ANNOTATOR,
    entry: str | None = None,
    model_version: str | None = None,
    priority: int = 0,
) -> AnnotationSegment:
    taxonomy = load_taxonomy(session)
    require(taxonomy, draft.label_key)
    validate_frames(video, draft.first_frame, draft.last_frame)
    segment = AnnotationSegment(
        video_id=video.id,
        first_frame=draft.first_frame,
        last_frame=draft.last_frame,
        label_key=draft.label_key,
        taxonomy_version=taxonomy.version,
        source=source,
        # An imported segment's annotator is whoever imported it (none from the command line),
        # so they cannot accept their own import.
        annotator_id=actor.id if actor else None,
        model_version=model_version,
        priority=priority,
    )
    SEGMENT.start(segment, entry)  # a draft, or a declared entry (status.SEGMENT.entries)
    session.add(segment)
    record(session, segment, actor, "created" if source != SegmentSource.IMPORT else "imported")
    return segment


def _may_edit(segment: AnnotationSegment, actor: User) -> None:
    if actor.role == Role.ADMIN:
        return
    if segment.annotator_id not in (None, actor.id):
        raise Forbidden(f"segment {segment.id} belongs to another annotator")


def update_segment(
    session: Session,
    segment: AnnotationSegment,
    actor: User,
    *,
    first_frame: int | None = None,
    last_frame: int | None = None,
    label_key: str | None = None,
) -> AnnotationSegment:
    _may_edit(segment, actor)
    if segment.status not in EDITABLE:
        raise LabellingError(
            f"status: a {segment.status} segment cannot be edited; withdraw or reopen it first"
        )
    video = get_video(session, segment.video_id)
    first = segment.first_frame if first_frame is None else first_frame
    last = segment.last_frame if last_frame is None else last_frame
    validate_frames(video, first, last)
    if label_key is not None:
        require(load_taxonomy(session), label_key)
        segment.label_key = label_key
    segment.first_frame, segment.last_frame = first, last
    SEGMENT.act(segment, "edit")  # a rejected segment becomes a draft again
    if segment.annotator_id is None:
        # A proposal (or a command-line import) becomes the fixing annotator's segment, so
        # someone else reviews it.
        segment.annotator_id = actor.id
    record(session, segment, actor, "updated")
    return segment


def delete_segment(session: Session, segment: AnnotationSegment, actor: User) -> None:
    _may_edit(segment, actor)
    if segment.status in (SegmentStatus.SUBMITTED, SegmentStatus.ACCEPTED):
        raise LabellingError(f"status: a {segment.status} segment cannot be deleted")
    if segment.status == SegmentStatus.DELETED:
        raise NotFound(f"segment {segment.id} is already deleted")
    SEGMENT.act(segment, "delete")
    record(session, segment, actor, "deleted")


def transition(
    session: Session, segment: AnnotationSegment, actor: User, action: str, comment: str | None
) -> AnnotationSegment:
    next_status(segment.status, action)  # refused before anything changes
    if action in REVIEW_ACTIONS:
        if actor.role == Role.ANNOTATOR and segment.annotator_id == actor.id:
            raise Forbidden("reviewer: nobody reviews their own segment")
        if action == "reject" and not (comment and comment.strip()):
            raise LabellingError("comment: a rejection needs a comment saying what to fix")
        if segment.label_key not in load_taxonomy(session, segment.taxonomy_version):
            raise LabellingError(
                f"label_key: {segment.label_key!r} is a placeholder; set a fine label first"
            )
        segment.reviewer_id = actor.id
        segment.review_comment = comment
    else:
        _may_edit(segment, actor)
        if action == "submit" and segment.annotator_id is None:
            segment.annotator_id = actor.id
    SEGMENT.act(segment, action)
    segment.updated_at = utcnow()
    record(session, segment, actor, action, comment)
    return segment


def history(session: Session, segment_id: int) -> list[SegmentEvent]:
    return list(
        session.scalars(
            select(SegmentEvent)
            .where(SegmentEvent.segment_id == segment_id)
            .order_by(SegmentEvent.at, SegmentEvent.id)
        )
    )
