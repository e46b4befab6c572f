"""Job reads in one place: the jobs list (newest first) and one job by id. The queue's claims
and transitions, which read the rows they change, stay in `queue.py`."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models.jobs import Job, JobStatus

MAX_LIMIT = 500


def list_jobs(session: Session, status: JobStatus | None = None, limit: int = 100) -> list[Job]:
    """The newest `limit` jobs (at most MAX_LIMIT), of one status if given."""
    query = select(Job).order_by(Job.id.desc()).limit(min(limit, MAX_LIMIT))
    if status is not None:
        query = query.where(Job.status == status)
    return list(session.scalars(query))


def job_by_id(session: Session, job_id: int) -> Job | None:
    return session.get(Job, job_id)
