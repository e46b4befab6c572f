"""What the API says about jobs: a job to queue (`JobIn`), a job in a list (`JobOut`) and one
job with its log (`JobDetail`)."""

from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field

from backend.models.jobs import JobKind, JobStatus


class JobIn(BaseModel):
    kind: JobKind
    params: dict = Field(default_factory=dict)


class JobOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: JobKind
    status: JobStatus
    params: dict
    progress: float
    message: str
    result: dict | None
    cancel_requested: bool
    worker_id: str | None
    attempts: int
    created_by_id: int | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    heartbeat_at: datetime | None


class JobDetail(JobOut):
    log: str
