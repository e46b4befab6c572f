from datetime import datetime

from sqlalchemy import JSON, ForeignKey, Index, String
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base
from vigil.classes import TransportMode
from vigil.inputs import KEYPOINTS, InputName, normalise


class Robot(Base):
    __tablename__ = "robots"

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    name: Mapped[str] = mapped_column(String(128), default="")
    ward: Mapped[str] = mapped_column(String(64))
    token_hash: Mapped[str | None] = mapped_column(String(128))
    token_created_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    assigned_model_id: Mapped[int | None] = mapped_column(ForeignKey("model_versions.id"))
    shadow_model_id: Mapped[int | None] = mapped_column(ForeignKey("model_versions.id"))
    running_model_version: Mapped[str | None] = mapped_column(String(64))
    # sha256 of the model file the robot says it runs (hello/heartbeat; None: an older agent,
    # or no model): the fleet is in sync only when it is the registry's sha256 of the target.
    running_model_sha256: Mapped[str | None] = mapped_column(String(64))
    agent_version: Mapped[str | None] = mapped_column(String(64))
    # What the robot said in its last hello it can feed a model (vigil.inputs); None: it did
    # not say (an older agent, or it never connected), which counts as keypoints only.
    inputs: Mapped[list[str] | None] = mapped_column(JSON)
    last_seen_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # The robot's last reported behaviour (vigil.classes.BehaviourState) and since when.
    behaviour_state: Mapped[str | None] = mapped_column(String(32))
    behaviour_since: Mapped[datetime | None] = mapped_column(UTCDateTime)
    behaviour_reason: Mapped[str | None] = mapped_column(String(500))
    last_seq: Mapped[int | None] = mapped_column()
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)

    @property
    def feeds(self) -> list[InputName]:
        """The inputs this robot can feed a model (keypoints only unless it said more)."""
        return robot_inputs(self.inputs)


def robot_inputs(reported: list[str] | None) -> list[InputName]:
    if reported is None:
        return [KEYPOINTS]
    try:
        return normalise(reported)
    except ValueError:  # a name this backend does not know: ignore it
        from vigil.inputs import ALL_INPUTS

        return normalise(name for name in reported if name in ALL_INPUTS)


class Transport(Base):
    __tablename__ = "transports"
    __table_args__ = (Index("ix_transports_active", "ended_at"),)

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"), index=True)
    mode: Mapped[TransportMode] = mapped_column(String(16))
    patient: Mapped[str | None] = mapped_column(String(64))
    location: Mapped[str | None] = mapped_column(String(128))
    started_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    ended_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # When a frame of this transport was last committed (stream-stalled detection).
    last_frame_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # When a frame showing the patient (any keypoint) was last committed, or the transport was
    # started (server clock): the alarm monitor's patient-not-seen check counts from there.
    last_patient_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    # The source's real frame rate from transport_start (None: not given, 30 assumed).
    fps: Mapped[float | None] = mapped_column()
