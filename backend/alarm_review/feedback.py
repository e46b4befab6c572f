"""A nurse's verdict becomes a pending label on the alarm's exact frame span.

The segment is stamped with the model version that raised the alarm and lands in the annotators'
review queue; alarms the nurse rejected as false come first (they are what the model got wrong).
"""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.labelling.status import SEGMENT
from backend.models import (
    Alarm,
    AnnotationSegment,
    FalseAlarmReason,
    Frame,
    SegmentEvent,
    SegmentSource,
    SegmentStatus,
    TaxonomyVersion,
    Verdict,
)
from backend.models.alarms import AlarmKind

#: Review-queue priority of a verdict segment (higher first).
VERDICT_PRIORITY: dict[Verdict, int] = {
    Verdict.FALSE_ALARM: 100,
    Verdict.UNSURE: 50,
    Verdict.TRUE_EMERGENCY: 10,
}

#: False-alarm reasons that name a fine label of the taxonomy exactly.
REASON_LABEL: dict[FalseAlarmReason, str] = {
    FalseAlarmReason.BENDING: "bending",
    FalseAlarmReason.SITTING_DOWN: "sitting_down",
    FalseAlarmReason.LYING_DOWN_DELIBERATELY: "lying_down_deliberately",
}


def proposed_label(verdict: Verdict, reason: FalseAlarmReason | None) -> str:
    """The fine label a verdict proposes.

    Only the three named false-alarm reasons pin down a fine label; every other verdict is a
    placeholder ``verdict:<verdict>[:<reason>]`` that the annotator replaces with a fine label.
    """
    if verdict == Verdict.FALSE_ALARM and reason in REASON_LABEL:
        return REASON_LABEL[reason]
    return f"{PLACEHOLDER_PREFIX}{verdict}" + (f":{reason}" if reason else "")


PLACEHOLDER_PREFIX = "verdict:"


def placeholder_name(label_key: str) -> str | None:
    """How a person reads a verdict placeholder (``verdict:false_alarm:other``): the nurse's
    verdict in words and what the annotator still has to do. None for any other key."""
    if not label_key.startswith(PLACEHOLDER_PREFIX):
        return None
    verdict, _, reason = label_key.removeprefix(PLACEHOLDER_PREFIX).partition(":")
    words = verdict.replace("_", " ")
    if reason:
        words += f" ({reason.replace('_', ' ')})"
    return f"Nurse verdict: {words}; choose the fine label"


def alarm_frame_span(session: Session, alarm: Alarm) -> tuple[int, int] | None:
    """(first, last) frame index of the alarm's frames in its video, or None if none are stored."""
    if alarm.video_id is None or alarm.first_seq is None:
        return None
    last_seq = alarm.last_seq if alarm.last_seq is not None else alarm.first_seq
    first, last = session.execute(
        select(func.min(Frame.index), func.max(Frame.index)).where(
            Frame.video_id == alarm.video_id,
            Frame.robot_id == alarm.robot_id,
            Frame.seq.between(alarm.first_seq, last_seq),
        )
    ).one()
    return None if first is None else (first, last)


def propose_label_from_verdict(
    session: Session, alarm: Alarm, actor_id: int | None
) -> AnnotationSegment | None:
    """Add (not commit) the pending segment for a resolved alarm; None for technical alarms,
    alarms without a verdict or without stored frames. Idempotent per alarm."""
    if alarm.verdict is None or alarm.kind not in (AlarmKind.EMERGENCY, AlarmKind.PAUSE):
        return None
    existing = session.scalar(
        select(AnnotationSegment).where(
            AnnotationSegment.alarm_id == alarm.id,
            AnnotationSegment.source == SegmentSource.NURSE_VERDICT,
        )
    )
    if existing is not None:
        return existing
    span = alarm_frame_span(session, alarm)
    if span is None:
        return None
    taxonomy_version = session.scalar(select(func.max(TaxonomyVersion.version)))
    if taxonomy_version is None:
        raise RuntimeError("no taxonomy version in the database; run the migrations")
    verdict = Verdict(alarm.verdict)
    reason = FalseAlarmReason(alarm.reason) if alarm.reason else None
    segment = AnnotationSegment(
        video_id=alarm.video_id,
        first_frame=span[0],
        last_frame=span[1],
        label_key=proposed_label(verdict, reason),
        taxonomy_version=taxonomy_version,
        source=SegmentSource.NURSE_VERDICT,
        priority=VERDICT_PRIORITY[verdict],
        alarm_id=alarm.id,
        model_version=alarm.model_version,
        review_comment=alarm.comment,
    )
    SEGMENT.start(segment, "propose")
    session.add(segment)
    session.flush()
    session.add(
        SegmentEvent(
            segment_id=segment.id,
            actor_id=actor_id,
            action="proposed_by_verdict",
            snapshot={
                "alarm_id": alarm.id,
                "verdict": str(verdict),
                "reason": str(reason) if reason else None,
                "label_key": segment.label_key,
                "first_frame": span[0],
                "last_frame": span[1],
                "model_version": alarm.model_version,
            },
            comment=alarm.comment,
        )
    )
    return segment


def review_queue(session: Session, limit: int = 100) -> list[AnnotationSegment]:
    """Pending segments, highest priority (nurse-rejected alarms) first, then oldest first."""
    return list(
        session.scalars(
            select(AnnotationSegment)
            .where(AnnotationSegment.status == SegmentStatus.PENDING)
            .order_by(
                AnnotationSegment.priority.desc(),
                AnnotationSegment.created_at,
                AnnotationSegment.id,
            )
            .limit(limit)
        )
    )
