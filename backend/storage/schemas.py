from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field, model_validator


class DayFigure(BaseModel):
    day: str  # YYYY-MM-DD (UTC)
    frames: int
    bytes: int
    cumulative_frames: int
    cumulative_bytes: int


class RobotFigure(BaseModel):
    robot_id: str | None  # None: imported recordings (URFD, OpenPose, labelling imports)
    frames: int
    bytes: int


class RetentionRunOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    dry_run: bool
    status: str
    job_id: int | None
    started_at: datetime
    finished_at: datetime | None
    cutoff_ts: float
    policy: dict
    dropped_frames: int
    dropped_bytes: int
    kept: dict
    by_day: dict
    partitions_dropped: list
    message: str


class NextRun(BaseModel):
    due_at: datetime | None  # when the schedule queues it (None: one is queued or running)
    cutoff_ts: float  # robot frames older than this may go at that run
    older_frames: int  # robot frames older than the cutoff: at most this many go
    older_bytes: int
    preview: RetentionRunOut | None  # the latest dry run: what the policy would drop, and why


class ArchiveOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    video_id: int | None
    video_name: str
    robot_id: str | None
    transport_id: str | None
    path: str
    sha256: str
    frame_count: int
    labelled_frames: int
    bytes: int
    first_ts: float | None
    last_ts: float | None
    created_at: datetime
    frames_in_database: int = 0


class StorageSummary(BaseModel):
    dialect: str
    computed_at: datetime
    total_frames: int
    payload_bytes: int  # blobs plus a per-row estimate (backend.storage.queries)
    database_bytes: int
    frames_bytes: int | None  # PostgreSQL: frames' partitions on disk
    free_bytes: int | None  # SQLite: free pages not yet given back
    partitions: int | None  # PostgreSQL: day partitions of frames
    days: list[DayFigure]
    robots: list[RobotFigure]
    policy: dict
    next_run: NextRun
    runs: list[RetentionRunOut]
    archives: int


class RetentionIn(BaseModel):
    dry_run: bool = True


class ArchiveIn(BaseModel):
    video_id: int | None = Field(default=None, ge=1, le=2**31 - 1)
    transport_id: str | None = Field(default=None, max_length=64)

    @model_validator(mode="after")
    def _one(self) -> "ArchiveIn":
        if (self.video_id is None) == (self.transport_id is None):
            raise ValueError("give exactly one of video_id and transport_id")
        return self
