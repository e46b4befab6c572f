"""First-run registry contents for `make run`: URFD (real data) split into training and gold
recordings, the default model registered, and one retrain job queued on the training split."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.models.jobs import Job, JobKind
from backend.models.registry import ModelVersion
from backend.models.videos import Split
from vigil.datasets import urfd
from worker import queue
from worker.db_data import import_urfd

# Every fifth fall and ADL recording is held out as the gold set (6 falls, 8 daily activities).
GOLD = [f"fall-{i:02d}" for i in range(5, 31, 5)] + [f"adl-{i:02d}" for i in range(5, 41, 5)]


def urfd_split() -> tuple[list[str], list[str]]:
    names = [f"fall-{i:02d}" for i in range(1, 31)] + [f"adl-{i:02d}" for i in range(1, 41)]
    return [n for n in names if n not in GOLD], list(GOLD)


def bootstrap(session: Session, default_model_dir: Path | None, urfd_dir=None) -> list[str]:
    """Idempotent; returns what it did."""
    done = []
    train, gold = urfd_split()
    if (urfd.default_dir() if urfd_dir is None else Path(urfd_dir)).exists():
        import_urfd(session, train, Split.TRAIN, urfd_dir)
        import_urfd(session, gold, Split.TEST, urfd_dir)
        done.append(f"URFD: {len(train)} training and {len(gold)} gold recordings")
    has_models = session.scalar(select(func.count()).select_from(ModelVersion))
    has_jobs = session.scalar(select(func.count()).select_from(Job))
    if not has_models and not has_jobs:
        if default_model_dir is not None and (default_model_dir / "manifest.json").exists():
            queue.enqueue(session, JobKind.REGISTER, {"path": str(default_model_dir)})
            done.append(f"queued: register {default_model_dir}")
        queue.enqueue(session, JobKind.RETRAIN, {"spec": "rf-default"})
        done.append("queued: retrain rf-default on the training split")
    return done
