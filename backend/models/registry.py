from datetime import datetime
from enum import StrEnum

from sqlalchemy import JSON, ForeignKey, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base
from vigil.classes import TransportMode


class ModelStatus(StrEnum):
    CANDIDATE = "candidate"
    APPROVED = "approved"
    PRODUCTION = "production"
    RETIRED = "retired"


class ModelVersion(Base):
    __tablename__ = "model_versions"

    id: Mapped[int] = mapped_column(primary_key=True)
    version: Mapped[str] = mapped_column(String(64), unique=True)
    mode: Mapped[TransportMode] = mapped_column(String(16))
    kind: Mapped[str] = mapped_column(String(32))  # svm, mlp, rf, temporal, ...
    format: Mapped[str] = mapped_column(String(8), default="onnx")
    file_path: Mapped[str] = mapped_column(String(512))
    sha256: Mapped[str] = mapped_column(String(64))
    manifest: Mapped[dict] = mapped_column(JSON)
    metrics: Mapped[dict] = mapped_column(JSON, default=dict)
    lineage: Mapped[dict] = mapped_column(JSON, default=dict)
    status: Mapped[ModelStatus] = mapped_column(String(16), default=ModelStatus.CANDIDATE)
    job_id: Mapped[int | None] = mapped_column(ForeignKey("jobs.id"))
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class DeploymentScope(StrEnum):
    ROBOT = "robot"
    WARD = "ward"
    FLEET = "fleet"


class DeploymentStatus(StrEnum):
    PENDING_APPROVAL = "pending_approval"  # signed off by one engineer, waiting for a second
    CANARY = "canary"
    ACTIVE = "active"
    ROLLED_BACK = "rolled_back"
    SUPERSEDED = "superseded"


class Deployment(Base):
    __tablename__ = "deployments"

    id: Mapped[int] = mapped_column(primary_key=True)
    model_version_id: Mapped[int] = mapped_column(ForeignKey("model_versions.id"))
    previous_model_version_id: Mapped[int | None] = mapped_column(ForeignKey("model_versions.id"))
    scope: Mapped[DeploymentScope] = mapped_column(String(8))
    target: Mapped[str | None] = mapped_column(String(64))  # robot id or ward
    shadow: Mapped[bool] = mapped_column(default=False)
    status: Mapped[DeploymentStatus] = mapped_column(String(16))
    gate_report: Mapped[dict] = mapped_column(JSON, default=dict)
    approved_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    second_approver_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    comment: Mapped[str | None] = mapped_column(Text)
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    # {"robots": [...], "canary": id|None, "previous": {robot_id: model_version_id|None}}
    rollout: Mapped[dict | None] = mapped_column(JSON)
    rolled_back_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    rollback_reason: Mapped[str | None] = mapped_column(Text)
    updated_at: Mapped[datetime | None] = mapped_column(
        UTCDateTime, default=utcnow, onupdate=utcnow
    )
