"""Periodic registry checks the worker runs between jobs (registry logic, so it lives in the
server domain): shadow disagreements queued for review, and the automatic rollback of a version
whose alarms nurses reject too often. Each sweep opens its own transaction."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Protocol

from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.registry import autorollback, shadow

log = logging.getLogger("vigil.worker")


class SweepSettings(Protocol):
    """What the sweeps read (the worker's settings carry it)."""

    false_alarm_budget: float
    false_alarm_min_verdicts: int


def shadow_disagreements(factory: sessionmaker[Session], settings: SweepSettings) -> None:
    with transaction(factory) as session:
        created = shadow.record_disagreements(session)
    if created:
        log.info("%d shadow disagreements queued for review", len(created))


def automatic_rollback(factory: sessionmaker[Session], settings: SweepSettings) -> None:
    with transaction(factory) as session:
        done = autorollback.check(
            session, settings.false_alarm_budget, settings.false_alarm_min_verdicts
        )
        for deployment, robots in done:
            log.warning(
                "rolled back deployment %s on %s: %s",
                deployment.id,
                robots,
                deployment.rollback_reason,
            )


Sweep = Callable[[sessionmaker[Session], SweepSettings], None]
SWEEPS: list[Sweep] = [shadow_disagreements, automatic_rollback]
