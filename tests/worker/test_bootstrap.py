"""First-run bootstrap: the URFD split into training and gold recordings, idempotent."""

from __future__ import annotations

from sqlalchemy import func, select

from backend.db import transaction
from backend.models.jobs import Job, JobKind
from backend.models.videos import Split, Video
from worker.bootstrap import bootstrap, urfd_split


def test_bootstrap_splits_urfd_and_queues_work_once(factory, trained_model_dir):
    train, gold = urfd_split()
    assert len(train) == 56 and len(gold) == 14 and not set(train) & set(gold)
    with transaction(factory) as session:
        done = bootstrap(session, trained_model_dir)
    assert done[0] == "URFD: 56 training and 14 gold recordings"
    with transaction(factory) as session:
        bootstrap(session, trained_model_dir)  # second run: nothing new
    with factory() as session:
        splits = dict(
            session.execute(select(Video.split, func.count()).group_by(Video.split)).all()
        )
        assert splits == {Split.TRAIN: 56, Split.TEST: 14}
        kinds = [j.kind for j in session.scalars(select(Job).order_by(Job.id))]
        assert kinds == [JobKind.REGISTER, JobKind.RETRAIN]
