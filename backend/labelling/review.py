"""The reviewers' queue: segments submitted or proposed, most informative first.

Rank 0: proposals from alarms a nurse rejected as false (the model was wrong in the ward).
Rank 1: model disagreements: shadow disagreements, model suggestions, and annotator segments
        whose class differs from the stored model decision on most of their frames.
Rank 2: the rest. Within a rank: higher priority, then oldest first.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.labelling.status import IN_REVIEW
from backend.labelling.taxonomy import load_taxonomy
from backend.models.alarms import Alarm, Verdict
from backend.models.annotations import AnnotationSegment, SegmentSource
from backend.models.videos import Frame, Video

NURSE_REJECTED, MODEL_DISAGREES, OTHER = 0, 1, 2
REASONS = {
    NURSE_REJECTED: "nurse rejected the alarm as false",
    MODEL_DISAGREES: "model disagrees",
    OTHER: "to review",
}


@dataclass(frozen=True, slots=True)
class QueueItem:
    segment: AnnotationSegment
    video: Video
    rank: int
    reason: str


def _model_disagrees(session: Session, segment: AnnotationSegment, video: Video, taxonomy) -> bool:
    label = taxonomy.get(segment.label_key)
    if label is None:
        return False
    decisions = session.scalars(
        select(Frame.decision).where(
            Frame.video_id == segment.video_id,
            Frame.index.between(segment.first_frame, segment.last_frame),
            Frame.decision.is_not(None),
        )
    ).all()
    if not decisions:
        return False
    most_common, count = Counter(decisions).most_common(1)[0]
    return most_common != label.decision(video.mode) and count * 2 > len(decisions)


def rank_of(session: Session, segment: AnnotationSegment, video: Video, taxonomy) -> int:
    if segment.source == SegmentSource.NURSE_VERDICT and segment.alarm_id is not None:
        verdict = session.scalar(select(Alarm.verdict).where(Alarm.id == segment.alarm_id))
        if verdict == Verdict.FALSE_ALARM:
            return NURSE_REJECTED
    if segment.source in (SegmentSource.SHADOW_DISAGREEMENT, SegmentSource.MODEL_SUGGESTION):
        return MODEL_DISAGREES
    if _model_disagrees(session, segment, video, taxonomy):
        return MODEL_DISAGREES
    return OTHER


def review_queue(session: Session, limit: int = 200) -> list[QueueItem]:
    taxonomy = load_taxonomy(session)
    rows = session.execute(
        select(AnnotationSegment, Video)
        .join(Video, Video.id == AnnotationSegment.video_id)
        .where(AnnotationSegment.status.in_(list(IN_REVIEW)))
    ).all()
    items = []
    for segment, video in rows:
        rank = rank_of(session, segment, video, taxonomy)
        items.append(QueueItem(segment, video, rank, REASONS[rank]))
    items.sort(key=lambda it: (it.rank, -it.segment.priority, it.segment.created_at, it.segment.id))
    return items[:limit]
