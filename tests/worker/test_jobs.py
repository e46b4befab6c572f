"""Jobs on real URFD recordings stored in the database: retrain registers a model with lineage,
gold-set metrics and plots; re-threshold derives a version; evaluate and what-if report."""

from __future__ import annotations

import json
from pathlib import Path

from sqlalchemy import func, select

from backend.db import transaction
from backend.jobs import queue
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.registry import ModelStatus, ModelVersion
from backend.models.users import Role, User
from backend.registry.gate import gate_report
from tests.registry_fixtures import GOLD, SMALL_GRID, TRAIN
from vigil.model_file import load_classifier
from worker.runner import Worker


def _run(factory, settings, kind, params, user_id=None) -> Job:
    with transaction(factory) as session:
        job_id = queue.enqueue(session, kind, params, user_id).id
    assert Worker(settings, factory, sweeps=[]).run_once() == job_id
    with factory() as session:
        return session.get(Job, job_id)


def test_retrain_on_urfd_registers_a_model_with_lineage_metrics_and_plots(
    factory, worker_settings, urfd_db
):
    with transaction(factory) as session:
        engineer = User(username="erin", password_hash="x", role=Role.ENGINEER)
        session.add(engineer)
        session.flush()
        engineer_id = engineer.id
    job = _run(
        factory, worker_settings, JobKind.RETRAIN, {"n_inner": 3, "grid": SMALL_GRID}, engineer_id
    )
    assert job.status == JobStatus.SUCCEEDED, job.log
    assert job.progress == 1.0 and "grid search: 2/2 configurations" in job.log
    with factory() as session:
        model = session.get(ModelVersion, job.result["model_version_id"])
        assert model.status == ModelStatus.CANDIDATE and model.job_id == job.id
        lineage = model.lineage
        assert lineage["started_by"]["username"] == "erin"
        assert lineage["training_videos"] == list(TRAIN)
        assert set(lineage["hyperparameters"]) == set(SMALL_GRID)
        assert lineage["taxonomy_version"] == 1 and lineage["feature_version"] >= 1
        assert len(lineage["data_sha256"]) == 64 and lineage["code_version"]
        gold = model.metrics["gold"]
        assert gold["falls_total"] == 2 and gold["adl_total"] == 2
        assert gold["sequences"] == list(GOLD)
        assert {"frame_recall", "frame_f1", "fp", "fp_d", "fn", "fn_d"} <= set(gold)
        assert len(gold["events"]) == 4 and gold["generated_data"] is False
        assert 0 < model.metrics["latency"]["p95_ms"] < 1000
        assert len(model.metrics["training"]["grid"]) == 2
        directory = Path(model.file_path).parent
        assert {p.name for p in (directory / "plots").glob("*.png")} >= {
            "roc_pr.png",
            "delay.png",
            "time_to_alarm.png",
        }
        # The registered file is what the manifest says (sha256 verified on load).
        assert load_classifier(directory).manifest.sha256 == model.sha256
        json.dumps(model.metrics)  # stored metrics are plain JSON
        gate = gate_report(model, false_alarm_budget=0.5, latency_ms=1000)
        assert gate["warnings"] == []
        checks = {c["name"]: c for c in gate["checks"]}
        split = checks["judged on gold recordings it was not trained on"]
        assert split["passed"] and split["detail"] == (
            "none of the 4 gold recordings is among its 12 training recordings"
        )
        assert checks["misses no fall of the gold set"]["passed"] == (gold["falls_detected"] == 2)


def test_retrain_without_enough_labelled_recordings_fails_with_a_clear_message(
    factory, worker_settings
):
    job = _run(factory, worker_settings, JobKind.RETRAIN, {"n_inner": 3})
    assert job.status == JobStatus.FAILED
    assert "no labelled recordings" in job.message
    bad = _run(factory, worker_settings, JobKind.RETRAIN, {"n_inner": "many"})
    assert bad.status == JobStatus.FAILED and "n_inner" in bad.message


def _register(factory, settings, model_dir) -> int:
    job = _run(factory, settings, JobKind.REGISTER, {"path": str(model_dir)})
    assert job.status == JobStatus.SUCCEEDED, job.log
    return job.result["model_version_id"]


def test_rethreshold_evaluate_and_what_if(factory, worker_settings, urfd_db, trained_model_dir):
    parent_id = _register(factory, worker_settings, trained_model_dir)
    job = _run(factory, worker_settings, JobKind.RETHRESHOLD, {"model_version_id": parent_id})
    assert job.status == JobStatus.SUCCEEDED, job.log
    with factory() as session:
        child = session.get(ModelVersion, job.result["model_version_id"])
        parent = session.get(ModelVersion, parent_id)
        assert child.lineage["parent"] == parent.version
        assert child.sha256 == parent.sha256  # same graph, new operating point
        # The register job records what the model was trained on (its manifest's recordings);
        # the child's graph is the parent's and its operating point chosen on the training split.
        assert parent.lineage["training_videos"] == list(TRAIN)
        assert child.lineage["training_videos"] == list(TRAIN)
        assert child.manifest["metrics"]["training_recordings"] == list(TRAIN)
        assert child.lineage["threshold_videos"] == list(TRAIN)
        assert child.metrics["gold"]["falls_total"] == 2
        assert len(child.metrics["rethreshold"]["delay_sweep"]["delay_s"]) == 151

    evaluation = _run(factory, worker_settings, JobKind.EVALUATE, {"model_version_id": parent_id})
    assert evaluation.status == JobStatus.SUCCEEDED, evaluation.log
    assert "falls" in evaluation.message

    # What-if with a 10 s delay: no Emergency run of these short recordings lasts that long,
    # so no alarm and no fall detected.
    params = {"model_version_id": parent_id, "threshold": 0.9, "delay_ms": 10_000}
    whatif = _run(factory, worker_settings, JobKind.WHATIF, params)
    assert whatif.status == JobStatus.SUCCEEDED, whatif.log
    result = whatif.result
    assert result["candidate"]["alarms"] == 0 and result["candidate"]["falls_detected"] == 0
    assert result["baseline"]["falls_detected"] == result["baseline"]["falls_total"] == 2
    assert result["change"]["falls_detected"] == -2
    assert len(result["events"]) == 4
    with factory() as session:
        assert session.scalar(select(func.count()).select_from(ModelVersion)) == 2


def test_register_refuses_a_tampered_model_file(
    factory, worker_settings, trained_model_dir, tmp_path
):
    import shutil

    copy = tmp_path / "tampered"
    shutil.copytree(trained_model_dir, copy)
    (copy / "model.onnx").write_bytes((copy / "model.onnx").read_bytes() + b"\0")
    job = _run(factory, worker_settings, JobKind.REGISTER, {"path": str(copy)})
    assert job.status == JobStatus.FAILED and "sha256 mismatch" in job.message
    with factory() as session:
        assert session.scalar(select(func.count()).select_from(ModelVersion)) == 0


def test_register_commits_once_nothing_when_the_gold_evaluation_fails(
    factory, worker_settings, trained_model_dir, monkeypatch
):
    from worker.jobs import register

    def failing_evaluation(*_args, **_kwargs):
        raise RuntimeError("gold set unreadable")

    monkeypatch.setattr(register, "gold_evaluation", failing_evaluation)
    job = _run(factory, worker_settings, JobKind.REGISTER, {"path": str(trained_model_dir)})
    assert job.status == JobStatus.FAILED and "gold set unreadable" in job.message
    with factory() as session:
        # The model is registered with its gold-set figures in one commit, or not at all.
        assert session.scalar(select(func.count()).select_from(ModelVersion)) == 0
    version = load_classifier(trained_model_dir).manifest.version
    assert not (Path(worker_settings.model_store_dir) / version).exists()
