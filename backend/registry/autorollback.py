"""Automatic rollback: a live deployment whose alarms nurses reject too often is rolled back.

The share counts alarms raised by the deployment's model version since the deployment started
that carry a nurse verdict; `false_alarm` verdicts are rejections. Nothing acts before
`min_verdicts` verdicts exist, so one early rejection does not undo a rollout. A rollback the
rollout service refuses (it would retire a mode's last keypoints-only fallback) is logged and
left to the engineers.
"""

from __future__ import annotations

import logging

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.models.alarms import Alarm, Verdict
from backend.models.registry import Deployment, ModelVersion
from backend.registry.rollout import LIVE, RolloutError, rollback

log = logging.getLogger(__name__)


def rejection_share(session: Session, deployment: Deployment) -> tuple[int, int]:
    """(rejected, judged) alarms of the deployment's version on its robots since it started."""
    model = session.get(ModelVersion, deployment.model_version_id)
    robots = (deployment.rollout or {}).get("assigned", [])
    rows = dict(
        session.execute(
            select(Alarm.verdict, func.count())
            .where(
                Alarm.model_version == model.version,
                Alarm.raised_at >= deployment.created_at,
                Alarm.verdict.is_not(None),
                Alarm.robot_id.in_(robots),
            )
            .group_by(Alarm.verdict)
        ).all()
    )
    return rows.get(Verdict.FALSE_ALARM, 0), sum(rows.values())


def check(session: Session, budget: float, min_verdicts: int) -> list[tuple[Deployment, list[str]]]:
    """Roll back every live deployment over budget; returns them with the robots changed."""
    done = []
    live = session.scalars(
        select(Deployment).where(Deployment.status.in_(LIVE), Deployment.shadow.is_(False))
    ).all()
    for deployment in live:
        rejected, judged = rejection_share(session, deployment)
        if judged >= min_verdicts and rejected / judged > budget:
            reason = (
                f"automatic: nurses rejected {rejected} of {judged} alarms "
                f"({rejected / judged:.0%} > budget {budget:.0%})"
            )
            try:
                done.append((deployment, rollback(session, deployment, reason)))
            except RolloutError as error:  # e.g. the mode's last keypoints-only fallback
                log.warning(
                    "automatic rollback of deployment %s refused: %s (%s)",
                    deployment.id,
                    error,
                    reason,
                )
    return done
