"""Frame storage at hospital scale: retention runs (what each run dropped and kept, and why)
and Parquet archives of videos (one file per video, sha256 in the manifest)."""

from datetime import datetime
from enum import StrEnum

from sqlalchemy import JSON, BigInteger, ForeignKey, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base


class RetentionRunStatus(StrEnum):
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"


class RetentionRun(Base):
    __tablename__ = "retention_runs"

    id: Mapped[int] = mapped_column(primary_key=True)
    dry_run: Mapped[bool] = mapped_column(default=False)
    status: Mapped[str] = mapped_column(String(16), default=RetentionRunStatus.RUNNING.value)
    job_id: Mapped[int | None] = mapped_column(ForeignKey("jobs.id", ondelete="SET NULL"))
    started_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime)
    cutoff_ts: Mapped[float] = mapped_column()  # robot frames older than this may go
    policy: Mapped[dict] = mapped_column(JSON, default=dict)  # the settings the run applied
    dropped_frames: Mapped[int] = mapped_column(BigInteger, default=0)
    dropped_bytes: Mapped[int] = mapped_column(BigInteger, default=0)
    # frames older than the cutoff that were kept, by reason (alarm_window, labelled, split,
    # lineage, downsampled)
    kept: Mapped[dict] = mapped_column(JSON, default=dict)
    by_day: Mapped[dict] = mapped_column(JSON, default=dict)  # day -> {"dropped", "kept"}
    partitions_dropped: Mapped[list] = mapped_column(JSON, default=list)
    message: Mapped[str] = mapped_column(Text, default="")


class FrameArchive(Base):
    __tablename__ = "frame_archives"

    id: Mapped[int] = mapped_column(primary_key=True)
    video_id: Mapped[int | None] = mapped_column(ForeignKey("videos.id", ondelete="SET NULL"))
    video_name: Mapped[str] = mapped_column(String(128), index=True)
    robot_id: Mapped[str | None] = mapped_column(String(64))
    transport_id: Mapped[str | None] = mapped_column(String(64))
    path: Mapped[str] = mapped_column(String(1024))  # the video's Parquet file
    manifest_path: Mapped[str] = mapped_column(String(1024))
    sha256: Mapped[str] = mapped_column(String(64))
    frame_count: Mapped[int] = mapped_column(default=0)
    labelled_frames: Mapped[int] = mapped_column(default=0)
    bytes: Mapped[int] = mapped_column(BigInteger, default=0)
    first_ts: Mapped[float | None] = mapped_column()
    last_ts: Mapped[float | None] = mapped_column()
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
