"""Periodic checks the worker runs between jobs."""

from __future__ import annotations

import logging

from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.models.jobs import JobKind
from backend.registry import autorollback, shadow
from backend.storage import partitions
from backend.storage import queries as storage_queries
from worker import queue
from worker.settings import WorkerSettings

log = logging.getLogger("vigil.worker")


def shadow_disagreements(factory: sessionmaker[Session], settings: WorkerSettings) -> None:
    with transaction(factory) as session:
        created = shadow.record_disagreements(session)
    if created:
        log.info("%d shadow disagreements queued for review", len(created))


def automatic_rollback(factory: sessionmaker[Session], settings: WorkerSettings) -> None:
    with transaction(factory) as session:
        done = autorollback.check(
            session, settings.false_alarm_budget, settings.false_alarm_min_verdicts
        )
        for deployment, robots in done:
            log.warning("rolled back deployment %s on %s: %s", deployment.id, robots,
                        deployment.rollback_reason)  # fmt: skip


def frame_partitions(factory: sessionmaker[Session], settings: WorkerSettings) -> None:
    """PostgreSQL: day partitions of frames exist partitions_ahead_days ahead (a frame with no
    partition still lands in the default partition; this keeps it small)."""
    with transaction(factory) as session:
        connection = session.connection()
        if connection.dialect.name != "postgresql" or not partitions.is_partitioned(connection):
            return
        created = partitions.ensure_ahead(connection, settings.partitions_ahead_days)
    if created:
        log.info("frame partitions created: %s", ", ".join(created))


def schedule_retention(factory: sessionmaker[Session], settings: WorkerSettings) -> None:
    """Queue a retention run when none is queued or running and the last one (not a dry run)
    was queued more than retention_interval_h ago."""
    with transaction(factory) as session:
        if storage_queries.due_retention(session, settings.retention_interval_h * 3600):
            queue.enqueue(session, JobKind.RETENTION, {})
            log.info("retention run queued (every %s h)", settings.retention_interval_h)


SWEEPS = [shadow_disagreements, automatic_rollback, frame_partitions, schedule_retention]
