from datetime import datetime
from enum import StrEnum

from sqlalchemy import JSON, ForeignKey, Index, String, Text, text
from sqlalchemy.orm import Mapped, mapped_column, relationship

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base
from backend.models.robots import Transport
from backend.models.users import User


class AlarmKind(StrEnum):
    EMERGENCY = "emergency"
    PAUSE = "pause"
    ROBOT_OFFLINE = "robot_offline"
    STREAM_STALLED = "stream_stalled"
    # The robot lacks an input its assigned model needs and classifies with its keypoints-only
    # fallback (or with what it has); raised and cleared by the robot's detection_status.
    DETECTION_DEGRADED = "detection_degraded"
    # A frame write blocked longer than storage_stall_seconds: alarms are pushed before they are
    # stored. Pushed unstored by the ingest writer (storage is what is stalled), then stored
    # raised and cleared once storage recovers (backend/ingest/failopen.py).
    STORAGE_STALLED = "storage_stalled"
    # Frames flow but none has shown the patient for patient_unseen_seconds: the robot lost its
    # patient (or never found them); raised and cleared by the alarm monitor.
    PATIENT_NOT_SEEN = "patient_not_seen"


class AlarmPriority(StrEnum):
    HIGH = "high"
    MEDIUM = "medium"
    TECHNICAL = "technical"


PRIORITY_OF_KIND = {
    AlarmKind.EMERGENCY: AlarmPriority.HIGH,
    AlarmKind.PAUSE: AlarmPriority.MEDIUM,
    AlarmKind.ROBOT_OFFLINE: AlarmPriority.TECHNICAL,
    AlarmKind.STREAM_STALLED: AlarmPriority.TECHNICAL,
    AlarmKind.DETECTION_DEGRADED: AlarmPriority.TECHNICAL,
    AlarmKind.STORAGE_STALLED: AlarmPriority.TECHNICAL,
    AlarmKind.PATIENT_NOT_SEEN: AlarmPriority.TECHNICAL,
}
#: Alarms about the system rather than the patient (no verdict statistics per model version).
TECHNICAL_KINDS = frozenset(
    kind for kind, priority in PRIORITY_OF_KIND.items() if priority == AlarmPriority.TECHNICAL
)


class AlarmState(StrEnum):
    OPEN = "open"
    ACKNOWLEDGED = "acknowledged"
    RESOLVED = "resolved"
    # The end of the escalation chain: an Emergency still unacknowledged after the last
    # escalation level. Latched (only a nurse's acknowledge or resolve ends it).
    MISSED = "missed"


class Verdict(StrEnum):
    TRUE_EMERGENCY = "true_emergency"
    FALSE_ALARM = "false_alarm"
    UNSURE = "unsure"


class FalseAlarmReason(StrEnum):
    BENDING = "bending"
    SITTING_DOWN = "sitting_down"
    LYING_DOWN_DELIBERATELY = "lying_down_deliberately"
    OTHER = "other"


class Alarm(Base):
    __tablename__ = "alarms"
    __table_args__ = (
        # One alarm per transport (robot for technical alarms) and kind is not resolved.
        Index(
            "uq_alarms_one_unresolved",
            "robot_id",
            "transport_key",
            "kind",
            unique=True,
            sqlite_where=text("state != 'resolved'"),
            postgresql_where=text("state != 'resolved'"),
        ),
        Index("ix_alarms_state_ward", "state", "ward"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[AlarmKind] = mapped_column(String(32))
    priority: Mapped[AlarmPriority] = mapped_column(String(16))
    state: Mapped[AlarmState] = mapped_column(String(16), default=AlarmState.OPEN)
    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"))
    transport_id: Mapped[str | None] = mapped_column(ForeignKey("transports.id"))
    # transport_id or '' (NULLs never collide in a unique index, so the key is never NULL).
    transport_key: Mapped[str] = mapped_column(String(64), default="")
    ward: Mapped[str] = mapped_column(String(64))
    patient: Mapped[str | None] = mapped_column(String(64))
    location: Mapped[str | None] = mapped_column(String(128))
    raised_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    acknowledged_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    acknowledged_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    resolved_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    resolved_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    verdict: Mapped[Verdict | None] = mapped_column(String(16))
    reason: Mapped[FalseAlarmReason | None] = mapped_column(String(32))
    comment: Mapped[str | None] = mapped_column(Text)
    escalation_level: Mapped[int] = mapped_column(default=0)
    escalated_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # Once missed: the last of the ward's further responders reached ("charge nurse", ...).
    escalated_to: Mapped[str | None] = mapped_column(String(64))
    # What the robot did about it, as it reported (protocol behaviour_changed): e.g.
    # emergency_stop since 12:03:05, then transporting once released.
    robot_state: Mapped[str | None] = mapped_column(String(32))
    robot_state_since: Mapped[datetime | None] = mapped_column(UTCDateTime)
    realarmed_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    video_id: Mapped[int | None] = mapped_column(ForeignKey("videos.id"))
    first_seq: Mapped[int | None] = mapped_column()
    last_seq: Mapped[int | None] = mapped_column()
    first_frame_ts: Mapped[float | None] = mapped_column()
    last_frame_ts: Mapped[float | None] = mapped_column()
    decision_count: Mapped[int] = mapped_column(default=0)
    model_version: Mapped[str | None] = mapped_column(String(64), index=True)
    threshold: Mapped[float | None] = mapped_column()
    delay_ms: Mapped[int | None] = mapped_column()
    # What a technical alarm is about, e.g. detection_degraded: {"missing_inputs", "reason",
    # "assigned_model", "running_model", "status_ts"}.
    details: Mapped[dict | None] = mapped_column(JSON)

    acknowledged_by_user: Mapped[User | None] = relationship(
        foreign_keys=[acknowledged_by_id], lazy="joined"
    )
    resolved_by_user: Mapped[User | None] = relationship(
        foreign_keys=[resolved_by_id], lazy="joined"
    )
    transport: Mapped[Transport | None] = relationship(lazy="joined", viewonly=True)

    @property
    def transport_ended_at(self) -> datetime | None:
        return self.transport.ended_at if self.transport is not None else None

    @property
    def acknowledged_by(self) -> str | None:
        return self.acknowledged_by_user.username if self.acknowledged_by_user else None

    @property
    def resolved_by(self) -> str | None:
        return self.resolved_by_user.username if self.resolved_by_user else None


class AlarmEvent(Base):
    """Audit trail: every transition of an alarm with who, when, from, to and comment."""

    __tablename__ = "alarm_events"
    __table_args__ = (Index("ix_alarm_events_at", "at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    alarm_id: Mapped[int] = mapped_column(ForeignKey("alarms.id", ondelete="CASCADE"), index=True)
    at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    actor_user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    actor: Mapped[str] = mapped_column(String(128))  # "nurse:alice", "robot:r1", "system"
    action: Mapped[str] = mapped_column(String(32))
    from_state: Mapped[AlarmState | None] = mapped_column(String(16))
    to_state: Mapped[AlarmState] = mapped_column(String(16))
    comment: Mapped[str | None] = mapped_column(Text)
