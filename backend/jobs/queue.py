"""The job queue lives in the `jobs` table.

Claiming: on PostgreSQL the oldest claimable row is selected `FOR UPDATE SKIP LOCKED`, so any
number of workers claim different jobs without waiting on each other. Every claim is also a
compare-and-set (`UPDATE ... WHERE id = :id AND <still claimable>`), which is what keeps a
claim safe on SQLite (no row locks there; one worker is the supported setup, two never
double-claim either, they just retry).

Claimable: queued jobs, and running jobs whose heartbeat is older than `stale_after_s` (their
worker died); a job claimed `max_attempts` times without finishing is failed instead.

State transitions are declared once, in JOB below (`vigil.states`).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import and_, or_, select, update
from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.models._types import utcnow
from backend.models.jobs import Job, JobKind, JobStatus
from vigil.states import IllegalTransition, StateMachine


class JobStateError(IllegalTransition):
    """A job change its status does not allow (HTTP 409)."""


JOB = StateMachine(
    JobStatus,
    edges={
        JobStatus.QUEUED: {JobStatus.RUNNING, JobStatus.CANCELLED},
        # running -> running: a dead worker's job is taken over
        JobStatus.RUNNING: {
            JobStatus.SUCCEEDED,
            JobStatus.FAILED,
            JobStatus.CANCELLED,
            JobStatus.RUNNING,
        },
        JobStatus.SUCCEEDED: set(),
        JobStatus.FAILED: set(),
        JobStatus.CANCELLED: set(),
    },
    initial=JobStatus.QUEUED,
    subject=lambda job: f"job {job.id}",
    error=JobStateError,
)
FINISHED = frozenset({JobStatus.SUCCEEDED, JobStatus.FAILED, JobStatus.CANCELLED})
MAX_LOG_CHARS = 200_000


def enqueue(
    session: Session, kind: JobKind | str, params: dict, created_by_id: int | None = None
) -> Job:
    job = Job(
        kind=JobKind(kind),
        status=JOB.initial,
        params=params,
        created_by_id=created_by_id,
        progress=0.0,
        message="queued",
        log="",
    )
    session.add(job)
    session.flush()
    return job


def request_cancel(session: Session, job: Job) -> None:
    """A queued job is cancelled at once; a running one stops at its next progress report."""
    if job.status == JobStatus.QUEUED:
        _finish(job, JobStatus.CANCELLED, "cancelled before it started")
    elif job.status == JobStatus.RUNNING:
        job.cancel_requested = True
        job.message = "cancel requested"
    else:
        JOB.check(job.status, JobStatus.CANCELLED, job)  # a finished job: raises


def _claimable(now: datetime, stale_after_s: float):
    stale_before = now - timedelta(seconds=stale_after_s)
    return or_(
        Job.status == JobStatus.QUEUED,
        and_(
            Job.status == JobStatus.RUNNING,
            or_(Job.heartbeat_at.is_(None), Job.heartbeat_at < stale_before),
        ),
    )


def claim_query(dialect: str, now: datetime, stale_after_s: float, kinds=None):
    """The oldest claimable job; row-locked with SKIP LOCKED where the database has it."""
    query = select(Job).where(_claimable(now, stale_after_s)).order_by(Job.created_at, Job.id)
    if kinds:
        query = query.where(Job.kind.in_(kinds))
    if dialect == "postgresql":
        query = query.with_for_update(skip_locked=True)
    return query.limit(1)


@dataclass(frozen=True)
class Claim:
    id: int
    kind: JobKind
    params: dict
    attempts: int
    created_by_id: int | None


def claim(
    factory: sessionmaker[Session],
    worker_id: str,
    stale_after_s: float = 30.0,
    max_attempts: int = 3,
    kinds: list[JobKind] | None = None,
) -> Claim | None:
    """Claim the oldest claimable job for `worker_id`, or None when there is none."""
    for _ in range(5):  # a lost compare-and-set (another worker won) just tries the next job
        with transaction(factory) as session:
            now = utcnow()
            query = claim_query(session.get_bind().dialect.name, now, stale_after_s, kinds)
            job = session.scalars(query).first()
            if job is None:
                return None
            if job.attempts >= max_attempts:
                _finish(job, JobStatus.FAILED, f"gave up after {job.attempts} attempts")
                continue
            taken_over = job.status == JobStatus.RUNNING
            claimed = session.execute(
                update(Job)
                .where(Job.id == job.id, _claimable(now, stale_after_s))
                .values(
                    **JOB.column(job.status, JobStatus.RUNNING, job),
                    worker_id=worker_id,
                    heartbeat_at=now,
                    started_at=now,
                    attempts=Job.attempts + 1,
                    message="taken over from a dead worker" if taken_over else "started",
                )
                .execution_options(synchronize_session=False)
            ).rowcount
            if claimed != 1:
                continue
            session.refresh(job)
            if taken_over:
                job.log = _append(
                    job.log,
                    f"[{now:%H:%M:%S}] {worker_id}: previous worker "
                    "stopped sending heartbeats; restarting",
                )
            return Claim(
                job.id, JobKind(job.kind), dict(job.params), job.attempts, job.created_by_id
            )
    return None


def _append(log: str, line: str) -> str:
    log = f"{log}{line}\n"
    return log[-MAX_LOG_CHARS:]


def _owned(session: Session, job_id: int, worker_id: str) -> Job | None:
    job = session.get(Job, job_id, with_for_update=True)
    if job is None or job.worker_id != worker_id or job.status != JobStatus.RUNNING:
        return None
    return job


def report(
    factory: sessionmaker[Session],
    job_id: int,
    worker_id: str,
    progress: float | None = None,
    message: str | None = None,
    log_lines: list[str] | None = None,
) -> bool | None:
    """Heartbeat with progress; returns cancel_requested, or None if the job is no longer ours."""
    with transaction(factory) as session:
        job = _owned(session, job_id, worker_id)
        if job is None:
            return None
        job.heartbeat_at = utcnow()
        if progress is not None:
            job.progress = max(0.0, min(1.0, float(progress)))
        if message is not None:
            job.message = message[:512]
        for line in log_lines or []:
            job.log = _append(job.log, line)
        return job.cancel_requested


def _finish(job: Job, status: JobStatus, message: str, result: dict | None = None) -> None:
    JOB.move(job, status)
    job.message = message[:512]
    job.finished_at = utcnow()
    if result is not None:
        job.result = result
    if status == JobStatus.SUCCEEDED:
        job.progress = 1.0
    job.log = _append(job.log or "", f"[{job.finished_at:%H:%M:%S}] {status}: {message}")


def finish(
    factory: sessionmaker[Session],
    job_id: int,
    worker_id: str,
    status: JobStatus,
    message: str,
    result: dict | None = None,
    log_lines: list[str] | None = None,
) -> bool:
    """Record the outcome; False if another worker took the job over meanwhile."""
    with transaction(factory) as session:
        job = _owned(session, job_id, worker_id)
        if job is None:
            return False
        for line in log_lines or []:
            job.log = _append(job.log, line)
        _finish(job, status, message, result)
        return True
