from datetime import datetime
from enum import StrEnum

from sqlalchemy import JSON, ForeignKey, Index, String, Text, func, text
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
    # The ward's Alert Manager (IHE PCD ACM: phones, pagers) has been unreachable longer than
    # alarm_distribution_down_s: alarms reach the board but not the nurses' phones. About no
    # robot (robot_id NULL, transport_key "ward:<ward>"); raised and cleared by the sender.
    ALARM_DISTRIBUTION_DOWN = "alarm_distribution_down"


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
    AlarmKind.ALARM_DISTRIBUTION_DOWN: AlarmPriority.TECHNICAL,
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
        # One alarm per transport (robot for technical alarms; ward for an alarm about no
        # robot) and kind is not resolved.
        Index(
            "uq_alarms_one_unresolved",
            func.coalesce(text("robot_id"), text("''")),
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
    # None: an alarm about no robot (alarm_distribution_down of a ward)
    robot_id: Mapped[str | None] = mapped_column(ForeignKey("robots.id"))
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
    # Acknowledged by someone who is not a Vigil user: a clinician accepting it on a phone of
    # the alarm distribution ("Anna Berg on Anna's phone").
    acknowledged_via: Mapped[str | None] = mapped_column(String(200))
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

    dispositions: Mapped[list["AlarmDisposition"]] = relationship(
        lazy="selectin", viewonly=True, order_by="AlarmDisposition.id"
    )

    @property
    def acknowledged_by(self) -> str | None:
        if self.acknowledged_by_user is not None:
            return self.acknowledged_by_user.username
        return self.acknowledged_via

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


class MessageStatus(StrEnum):
    """An alarm change's ORU^R40 in the outbox (`backend.distribution.state`)."""

    PENDING = "pending"  # queued; sent again until the Alert Manager acknowledges it
    DELIVERED = "delivered"  # the Alert Manager answered AA
    REFUSED = "refused"  # AE: the Alert Manager will not take it as it is (not resent)


class AlarmMessage(Base):
    """The outbox of alarm distribution: one ORU^R40 per alarm change, queued in the change's
    own transaction, kept until the Alert Manager acknowledges it."""

    __tablename__ = "alarm_messages"
    __table_args__ = (Index("ix_alarm_messages_status_id", "status", "id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    alarm_id: Mapped[int] = mapped_column(ForeignKey("alarms.id", ondelete="CASCADE"), index=True)
    # One message per change: the audit entry of the change
    event_id: Mapped[int] = mapped_column(
        ForeignKey("alarm_events.id", ondelete="CASCADE"), unique=True
    )
    change: Mapped[str] = mapped_column(String(16))
    ward: Mapped[str] = mapped_column(String(64))
    destination: Mapped[str] = mapped_column(String(255))  # "host:port" of the Alert Manager
    # MSH-10, the same on every resend (the Alert Manager recognises a repeat by it)
    control_id: Mapped[str] = mapped_column(String(32), unique=True)
    facility: Mapped[str] = mapped_column(String(64), default="HOSPITAL")  # MSH-4
    # What the change reports (AlertReport JSON), stored with the change; the sender builds
    # the ORU^R40 from it before the first send and keeps it in payload (every resend is the
    # same message)
    report: Mapped[str | None] = mapped_column(Text)  # None: queued before 0017, payload built
    payload: Mapped[str | None] = mapped_column(Text)  # the ORU^R40, ER7
    status: Mapped[MessageStatus] = mapped_column(String(16), default=MessageStatus.PENDING)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    attempts: Mapped[int] = mapped_column(default=0)
    last_attempt_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    acked_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    ack_code: Mapped[str | None] = mapped_column(String(2))
    last_error: Mapped[str | None] = mapped_column(Text)


class AlarmDisposition(Base):
    """What the Alert Manager reported of an alarm on a clinician's device (ORA^R41)."""

    __tablename__ = "alarm_dispositions"

    id: Mapped[int] = mapped_column(primary_key=True)
    alarm_id: Mapped[int] = mapped_column(ForeignKey("alarms.id", ondelete="CASCADE"), index=True)
    message_id: Mapped[int | None] = mapped_column(
        ForeignKey("alarm_messages.id", ondelete="SET NULL")
    )
    # MSH-10 of the ORA^R41: a status the Alert Manager sends again is recorded once
    control_id: Mapped[str] = mapped_column(String(64), unique=True)
    disposition: Mapped[str] = mapped_column(String(16))  # delivered, read, accepted, rejected
    clinician_id: Mapped[str] = mapped_column(String(64))
    clinician: Mapped[str] = mapped_column(String(128))
    device: Mapped[str] = mapped_column(String(128))
    at: Mapped[datetime] = mapped_column(UTCDateTime)
    received_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
