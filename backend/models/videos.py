from datetime import datetime
from enum import StrEnum

from sqlalchemy import (
    JSON,
    BigInteger,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base
from vigil.classes import Decision, TransportMode


class Split(StrEnum):
    TRAIN = "train"
    TEST = "test"
    UNASSIGNED = "unassigned"


class Video(Base):
    """A recording: an imported dataset sequence, an OpenPose directory or a robot transport."""

    __tablename__ = "videos"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(128), unique=True)
    source: Mapped[str] = mapped_column(String(32))  # urfd, openpose, export, robot, generated
    generated: Mapped[bool] = mapped_column(default=False)
    mode: Mapped[TransportMode] = mapped_column(String(16))
    camera: Mapped[str | None] = mapped_column(String(64))
    location: Mapped[str | None] = mapped_column(String(128))
    fps: Mapped[float] = mapped_column(default=30.0)
    person: Mapped[str | None] = mapped_column(String(64))  # pseudonym
    split: Mapped[Split] = mapped_column(String(16), default=Split.UNASSIGNED)
    transport_id: Mapped[str | None] = mapped_column(ForeignKey("transports.id"), index=True)
    robot_id: Mapped[str | None] = mapped_column(ForeignKey("robots.id"))
    rgb_path: Mapped[str | None] = mapped_column(String(512))
    depth_path: Mapped[str | None] = mapped_column(String(512))
    frame_count: Mapped[int] = mapped_column(default=0)
    # Size of the keypoints' coordinate space (pixels); None when keypoints are normalised.
    image_width: Mapped[float | None] = mapped_column()
    image_height: Mapped[float | None] = mapped_column()
    # Pinhole camera of the keypoints' image: {"fx", "fy", "cx", "cy"} in pixels (3D view).
    intrinsics: Mapped[dict | None] = mapped_column(JSON)
    # Where the RGB picture sits in the clip's frames: {"x", "y", "width", "height"} in pixels
    # (URFD clips put depth left and RGB right); None = the whole frame.
    rgb_crop: Mapped[dict | None] = mapped_column(JSON)
    # Clip frame = skeleton frame index + offset (clamped to the clip); URFD keypoints lag by 1.
    rgb_frame_offset: Mapped[int] = mapped_column(default=0, server_default="0")
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    # Smallest and largest ts of the video's frames (None: not known, e.g. no frames yet).
    # Every writer of frames widens it (`cover`) in the same transaction; reads by video add
    # `ts BETWEEN` these so that PostgreSQL reads only the day partitions that hold the video
    # (`backend.storage.frame_reads`). Retention only removes frames: the range stays a bound.
    first_frame_ts: Mapped[float | None] = mapped_column()
    last_frame_ts: Mapped[float | None] = mapped_column()

    def cover(self, first_ts: float, last_ts: float) -> None:
        """Widen the frame time range to include [first_ts, last_ts]."""
        self.first_frame_ts, self.last_frame_ts = widened(
            self.first_frame_ts, self.last_frame_ts, first_ts, last_ts
        )


def widened(
    first: float | None, last: float | None, new_first: float, new_last: float
) -> tuple[float, float]:
    """The range [first, last] (None: empty) widened to include [new_first, new_last]."""
    return (
        new_first if first is None else min(first, new_first),
        new_last if last is None else max(last, new_last),
    )


class Frame(Base):
    """One classified skeleton frame; keypoints, depth and floor measures as little-endian
    float32 blobs.

    On PostgreSQL the table is partitioned by day of `ts` (migration 0011,
    `backend/storage/partitions.py`): there the primary key is (id, ts) and both unique keys
    carry ts too (a partition key must be part of every unique key); a resent frame carries
    the same ts, so deduplication by robot + seq is unchanged. Indexes serve the real reads:
    alarm replay (video_id, ts) or (robot_id, ts), labelling timeline, training export and
    what-if (video_id, index), ingest deduplication (robot_id, seq) and retention (robot_id, ts).
    """

    __tablename__ = "frames"
    __table_args__ = (
        UniqueConstraint("video_id", "index", name="uq_frames_video_index"),
        UniqueConstraint("robot_id", "seq", name="uq_frames_robot_seq"),
        Index("ix_frames_video_ts", "video_id", "ts"),
        Index("ix_frames_robot_ts", "robot_id", "ts"),
    )

    # BIGINT on PostgreSQL (a hospital passes 2**31 frames in a few years); SQLite's rowid.
    id: Mapped[int] = mapped_column(
        BigInteger().with_variant(Integer(), "sqlite"), primary_key=True
    )
    video_id: Mapped[int] = mapped_column(ForeignKey("videos.id", ondelete="CASCADE"))
    index: Mapped[int] = mapped_column()
    ts: Mapped[float] = mapped_column()  # seconds (unix time for robot frames)
    robot_id: Mapped[str | None] = mapped_column(String(64))
    seq: Mapped[int | None] = mapped_column()
    keypoints: Mapped[bytes] = mapped_column(LargeBinary)
    depth: Mapped[bytes | None] = mapped_column(LargeBinary)
    floor: Mapped[bytes | None] = mapped_column(LargeBinary)  # vigil.skeleton.encode_floor
    decision: Mapped[Decision | None] = mapped_column(String(16))
    scores: Mapped[dict | None] = mapped_column(JSON)
    model_version: Mapped[str | None] = mapped_column(String(64))
    threshold: Mapped[float | None] = mapped_column()
    delay_ms: Mapped[int | None] = mapped_column()
    shadow_decision: Mapped[Decision | None] = mapped_column(String(16))
    shadow_scores: Mapped[dict | None] = mapped_column(JSON)
    shadow_model_version: Mapped[str | None] = mapped_column(String(64))
