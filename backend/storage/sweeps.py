"""Periodic storage checks the worker runs between jobs: day partitions of frames kept ahead
(PostgreSQL) and the scheduled retention run. Each sweep opens its own transaction."""

from __future__ import annotations

import logging
from typing import Protocol

from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.jobs import queue
from backend.models.jobs import JobKind
from backend.storage import partitions
from backend.storage import queries as storage_queries

log = logging.getLogger("vigil.worker")


class StorageSweepSettings(Protocol):
    """What the storage sweeps read (the worker's settings carry it)."""

    partitions_ahead_days: int
    retention_interval_h: float


def frame_partitions(factory: sessionmaker[Session], settings: StorageSweepSettings) -> None:
    """PostgreSQL: day partitions of frames exist partitions_ahead_days ahead (a frame with no
    partition still lands in the default partition; this keeps it small)."""
    with transaction(factory) as session:
        connection = session.connection()
        if connection.dialect.name != "postgresql" or not partitions.is_partitioned(connection):
            return
        created = partitions.ensure_ahead(connection, settings.partitions_ahead_days)
    if created:
        log.info("frame partitions created: %s", ", ".join(created))


def schedule_retention(factory: sessionmaker[Session], settings: StorageSweepSettings) -> None:
    """Queue a retention run when none is queued or running and the last one (not a dry run)
    was queued more than retention_interval_h ago."""
    with transaction(factory) as session:
        if storage_queries.due_retention(session, settings.retention_interval_h * 3600):
            queue.enqueue(session, JobKind.RETENTION, {})
            log.info("retention run queued (every %s h)", settings.retention_interval_h)


SWEEPS = [frame_partitions, schedule_retention]
