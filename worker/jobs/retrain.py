"""Retrain: grid search + threshold + delay on the accepted labels of the training recordings
(imported datasets such as URFD and labelled robot recordings), evaluate on the gold set,
register the result as a candidate."""

from __future__ import annotations

import shutil
from dataclasses import replace
from datetime import UTC, datetime

import numpy as np

from backend.jobs.params import RetrainParams, parse
from backend.models.videos import Split
from backend.storage.archive import import_archive
from backend.storage.queries import archive_by_id
from worker.context import JobContext
from worker.db_data import frame_data, labelled_videos
from worker.grid import GridBackend
from worker.jobs.common import gold_evaluation, reload, started_by
from worker.registration import register, store_path
from worker.training.cross_validation import select
from worker.training.estimators import ModelSpec
from worker.training.publish import publish
from worker.training.selection import evaluate
from worker.training.specs import SPECS
from worker.training.trainers import SklearnTrainer


def spec_for(params: RetrainParams) -> ModelSpec:
    if params.spec not in SPECS:
        raise ValueError(f"invalid job parameter spec: choose one of {sorted(SPECS)}")
    spec = SPECS[params.spec]
    if params.grid is not None:
        unknown = set(params.grid) - set(spec.grid)
        if unknown:
            raise ValueError(f"invalid job parameter grid: {sorted(unknown)} not in {spec.name}")
        spec = replace(spec, grid={**spec.grid, **params.grid})
    return spec


def restore_archives(session, archive_ids: list[int]) -> list[int]:
    """Import the chosen archived videos again (if their frames were dropped): the ids of their
    videos. A write: run it in a unit of work that commits (`context.write()`), not in a read
    session, or the restored frames and labels are lost when that session closes."""
    restored = []
    for archive_id in archive_ids:
        found = archive_by_id(session, archive_id)
        if found is None:
            raise ValueError(f"invalid job parameter archive_ids: archive {archive_id} not found")
        restored.append(import_archive(session, found).id)
    return restored


def with_archived(session, videos: list, restored: list[int], mode) -> list:
    """The training videos plus the restored archived ones (those with accepted labels train)."""
    known = {v.id for v in videos}
    extra = [v for v in labelled_videos(session, mode, None, restored) if v.id not in known]
    return videos + extra


def run(context: JobContext) -> dict:
    params = parse(RetrainParams, context.params)
    spec = spec_for(params)
    context.progress(0.02, "loading labelled training recordings")
    restored: list[int] = []
    if params.archive_ids:
        with context.write() as session:
            restored = restore_archives(session, params.archive_ids)
    with context.read() as session:
        videos = labelled_videos(
            session, params.mode, None if params.video_ids else Split.TRAIN, params.video_ids
        )
        if params.archive_ids:
            videos = with_archived(session, videos, restored, params.mode)
        data = frame_data(session, videos, params.mode)
        who = started_by(session, context)
    falls = int(data.is_positive_sequence.sum())
    if falls < params.n_inner or len(data.names) - falls < params.n_inner:
        raise ValueError(
            f"need at least {params.n_inner} recordings with and without a fall for "
            f"{params.n_inner}-fold selection; have {falls} and {len(data.names) - falls}"
        )
    context.log(
        f"{len(data.names)} recordings ({falls} with a fall), {len(data.target)} frames, "
        f"data {data.data_sha256[:12]}"
    )
    backend = GridBackend(context.settings.dask_scheduler, context.settings.grid_n_jobs)
    trainer = SklearnTrainer(spec)
    n_configs = len(spec.configurations())
    context.progress(0.05, f"grid search: {n_configs} configurations on {backend.description}")
    with backend.active():
        selected = select(trainer, data, np.arange(len(data.names)), params.n_inner, params.stride)
    context.progress(0.65, f"grid search: {n_configs}/{n_configs} configurations")
    context.progress(
        0.7,
        f"selected {selected.params}; threshold {selected.threshold:.3f}, "
        f"delay {selected.delay_s * 1000:.0f} ms; exporting ONNX",
    )
    version = params.version or (
        f"{spec.name}-{params.mode.value}-{datetime.now(UTC):%Y%m%dT%H%M%S}-j{context.job_id}"
    )
    directory = store_path(context.settings.model_store_dir, version)
    if directory.exists():
        raise ValueError(f"invalid job parameter version: {version} exists in the model store")
    try:
        inner = evaluate(selected.oof, selected.threshold, selected.delay_s)
        publish(
            trainer,
            selected,
            data,
            directory,
            version=version,
            metrics={"dataset": "database", "videos": len(data.names)},
        )
        classifier = reload(directory)
        context.progress(0.8, "evaluating on the gold set")
        with context.read() as session:
            metrics = gold_evaluation(
                session, classifier, directory, params.mode, selected.delay_sweep
            )
        metrics["training"] = {
            "note": "inner out-of-fold scores of the training recordings; threshold and delay "
            "were chosen on these same scores, so they are optimistic",
            "grid": selected.grid_scores,
            "evaluation": inner,
            "seconds": selected.seconds,
        }
        context.progress(0.95, "registering")
        with context.result() as session:
            model = register(
                session,
                directory,
                context.settings.model_store_dir,
                lineage={
                    "started_by": who,
                    "spec": spec.name,
                    "family": spec.family,
                    "hyperparameters": {
                        k: (list(v) if isinstance(v, tuple) else v)
                        for k, v in selected.params.items()
                    },
                    "grid": {
                        k: [list(x) if isinstance(x, tuple) else x for x in v]
                        for k, v in spec.grid.items()
                    },
                    "training_videos": data.names,
                    "n_inner": params.n_inner,
                    "stride": params.stride,
                    "grid_backend": backend.description,
                    "parent": None,
                },
                metrics=metrics,
                job_id=context.job_id,
                created_by_id=context.created_by_id,
            )
            model_id = model.id
    except BaseException:
        shutil.rmtree(directory, ignore_errors=True)
        raise
    gold = metrics.get("gold") or {}
    summary = f"registered {version}"
    if gold:
        summary += (
            f": gold set {gold['falls_detected']}/{gold['falls_total']} falls, "
            f"{gold['adl_false_alarms']}/{gold['adl_total']} false alarms"
        )
    return {"summary": summary, "model_version_id": model_id, "version": version}
