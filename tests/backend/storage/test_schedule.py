"""The worker queues a retention run every retention_interval_h (never two at once; a dry run
does not count as the scheduled run) and keeps PostgreSQL's day partitions ahead."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from sqlalchemy import select

from backend.db import transaction
from backend.models import Job, JobKind, JobStatus
from backend.storage import partitions
from backend.storage.sweeps import frame_partitions, schedule_retention
from worker.settings import WorkerSettings


def retention_jobs(factory) -> list[Job]:
    with transaction(factory) as session:
        return session.scalars(
            select(Job).where(Job.kind == JobKind.RETENTION).order_by(Job.id)
        ).all()


def test_retention_is_scheduled_once_per_interval(database_url, session_factory):
    settings = WorkerSettings(database_url=database_url, retention_interval_h=24)
    schedule_retention(session_factory, settings)
    schedule_retention(session_factory, settings)  # one queued: no second
    jobs = retention_jobs(session_factory)
    assert [(j.status, j.params) for j in jobs] == [(JobStatus.QUEUED, {})]
    with transaction(session_factory) as session:
        job = session.get(Job, jobs[0].id)
        job.status = JobStatus.SUCCEEDED
        job.created_at = datetime.now(UTC) - timedelta(hours=23)
        session.add(
            Job(kind=JobKind.RETENTION, status=JobStatus.SUCCEEDED, params={"dry_run": True})
        )
    schedule_retention(session_factory, settings)
    assert len(retention_jobs(session_factory)) == 2  # not due yet (the dry run is not a run)
    with transaction(session_factory) as session:
        session.get(Job, jobs[0].id).created_at = datetime.now(UTC) - timedelta(hours=25)
    schedule_retention(session_factory, settings)
    assert len(retention_jobs(session_factory)) == 3


def test_partitions_are_kept_ahead(database_url, session_factory):
    settings = WorkerSettings(database_url=database_url, partitions_ahead_days=10)
    frame_partitions(session_factory, settings)  # SQLite: nothing to do
    with transaction(session_factory) as session:
        connection = session.connection()
        if connection.dialect.name == "postgresql":
            today = partitions.today()
            assert set(range(today - 1, today + 11)) <= set(partitions.day_partitions(connection))
