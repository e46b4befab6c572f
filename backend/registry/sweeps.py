"""Periodic checks the worker runs between jobs."""

from __future__ import annotations

import logging

from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.registry import autorollback, shadow
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


SWEEPS = [shadow_disagreements, automatic_rollback]
