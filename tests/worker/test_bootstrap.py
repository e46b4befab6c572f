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


def test_make_run_seeding_holds_each_urfd_recording_once(factory):
    """`make run` seeds URFD twice over: `seed-demo` into the labelling workspace, then the
    worker's bootstrap. One importer, so 56 training and 14 gold recordings, each once, with the
    one fine-label map."""
    from backend.demo import seed_urfd
    from backend.models.annotations import AnnotationSegment
    from vigil.datasets import urfd

    with transaction(factory) as session:
        assert len(seed_urfd(session).created) == 70
    with transaction(factory) as session:
        assert bootstrap(session, None)[0] == "URFD: 56 training and 14 gold recordings"
    with factory() as session:
        videos = session.execute(select(Video.name, Video.split).where(Video.source == "urfd"))
        splits = dict(videos.all())
        assert sorted(splits) == sorted(urfd.NAMES)  # each recording once, by its own name
        assert sum(s == Split.TRAIN for s in splits.values()) == 56
        assert sum(s == Split.TEST for s in splits.values()) == 14
        labels = set(session.scalars(select(AnnotationSegment.label_key).distinct()))
        assert labels == {label for m in urfd.FINE_LABELS.values() for label in m.values()}


def test_the_demo_model_is_trained_on_the_training_split_and_judged_on_the_gold_set(
    factory, tmp_path
):
    """`make run`'s keypoints-only model (trained as the floor model is, `train_demo_model`):
    none of its training recordings is gold, its rows are the training split's frames, and
    the gate judges it on the 14 gold recordings it never saw."""
    from backend.registry.gate import gate_report
    from vigil.datasets import urfd
    from vigil.model_file import read_manifest
    from worker.bootstrap import register_model_dir, train_keypoints

    train, gold = urfd_split()
    out = tmp_path / "keypoints-walking"
    train_keypoints(out)
    manifest, _ = read_manifest(out)
    assert manifest.training_recordings == train
    assert not set(manifest.training_recordings) & set(gold)
    assert manifest.metrics["training_rows"] == sum(len(s.target) for s in urfd.load(None, train))
    assert manifest.metrics["urfd_gold_recordings_left_out"] == gold

    with transaction(factory) as session:
        bootstrap(session, None)
        model = register_model_dir(session, out, tmp_path / "store")
        assert model.lineage["training_videos"] == train
        assert sorted(model.metrics["gold"]["sequences"]) == sorted(gold)
        gate = gate_report(model, false_alarm_budget=1.0, latency_ms=1000)
    split = next(c for c in gate["checks"] if c["name"].startswith("judged on gold"))
    assert split["passed"], split
    assert split["detail"] == "none of the 14 gold recordings is among its 56 training recordings"
    assert gate["split"] == {"gold_recordings": 14, "training_recordings": 56, "overlap": []}
