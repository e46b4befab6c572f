"""SQLAlchemy 2 typed models, one module per domain."""

from backend.models.alarms import (
    Alarm,
    AlarmDisposition,
    AlarmEvent,
    AlarmKind,
    AlarmMessage,
    AlarmPriority,
    AlarmState,
    FalseAlarmReason,
    MessageStatus,
    Verdict,
)
from backend.models.annotations import AnnotationSegment, SegmentEvent, SegmentSource, SegmentStatus
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.registry import (
    Deployment,
    DeploymentScope,
    DeploymentStatus,
    ModelStatus,
    ModelVersion,
)
from backend.models.robots import Robot, Transport
from backend.models.storage import FrameArchive, RetentionRun
from backend.models.taxonomy import TaxonomyLabel, TaxonomyVersion
from backend.models.users import RevokedSession, Role, User
from backend.models.videos import Frame, Split, Video

__all__ = [
    "Alarm",
    "AlarmDisposition",
    "AlarmEvent",
    "AlarmKind",
    "AlarmMessage",
    "AlarmPriority",
    "AlarmState",
    "AnnotationSegment",
    "MessageStatus",
    "Deployment",
    "DeploymentScope",
    "DeploymentStatus",
    "FalseAlarmReason",
    "Frame",
    "FrameArchive",
    "Job",
    "JobKind",
    "JobStatus",
    "ModelStatus",
    "ModelVersion",
    "RetentionRun",
    "RevokedSession",
    "Robot",
    "Role",
    "SegmentEvent",
    "SegmentSource",
    "SegmentStatus",
    "Split",
    "TaxonomyLabel",
    "TaxonomyVersion",
    "Transport",
    "User",
    "Verdict",
    "Video",
]
