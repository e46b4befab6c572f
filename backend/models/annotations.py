from datetime import datetime
from enum import StrEnum

from sqlalchemy import JSON, ForeignKey, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base


class SegmentStatus(StrEnum):
    DRAFT = "draft"
    PENDING = "pending"  # proposed by a nurse verdict, a model or a shadow disagreement
    SUBMITTED = "submitted"
    ACCEPTED = "accepted"
    REJECTED = "rejected"
    DELETED = "deleted"  # kept (not removed) so the segment's history survives


class SegmentSource(StrEnum):
    ANNOTATOR = "annotator"
    NURSE_VERDICT = "nurse_verdict"
    MODEL_SUGGESTION = "model_suggestion"
    SHADOW_DISAGREEMENT = "shadow_disagreement"
    IMPORT = "import"


class AnnotationSegment(Base):
    """Frames first_frame..last_frame (inclusive, exact frame numbers) carry one fine label."""

    __tablename__ = "annotation_segments"

    id: Mapped[int] = mapped_column(primary_key=True)
    video_id: Mapped[int] = mapped_column(ForeignKey("videos.id", ondelete="CASCADE"), index=True)
    first_frame: Mapped[int] = mapped_column()
    last_frame: Mapped[int] = mapped_column()
    label_key: Mapped[str] = mapped_column(String(64))
    taxonomy_version: Mapped[int] = mapped_column(ForeignKey("taxonomy_versions.version"))
    status: Mapped[SegmentStatus] = mapped_column(
        String(16), default=SegmentStatus.DRAFT, index=True
    )
    source: Mapped[SegmentSource] = mapped_column(String(32), default=SegmentSource.ANNOTATOR)
    priority: Mapped[int] = mapped_column(default=0)  # review queue: higher first
    annotator_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    reviewer_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    review_comment: Mapped[str | None] = mapped_column(Text)
    alarm_id: Mapped[int | None] = mapped_column(ForeignKey("alarms.id"))
    model_version: Mapped[str | None] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow, onupdate=utcnow)


class SegmentEvent(Base):
    """History of a segment: every change with who, when and the values after it."""

    __tablename__ = "segment_events"

    id: Mapped[int] = mapped_column(primary_key=True)
    segment_id: Mapped[int] = mapped_column(
        ForeignKey("annotation_segments.id", ondelete="CASCADE"), index=True
    )
    at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    actor_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    action: Mapped[str] = mapped_column(String(32))
    snapshot: Mapped[dict] = mapped_column(JSON)
    comment: Mapped[str | None] = mapped_column(Text)
