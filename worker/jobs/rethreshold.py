"""Re-threshold: keep a model's ONNX graph, re-choose threshold and delay on new labelled data
(the detection code's rules), evaluate on the gold set, register as a new candidate version."""

from __future__ import annotations

import shutil
from datetime import UTC, datetime

from backend.jobs.params import RethresholdParams, parse
from backend.models.videos import Split
from vigil.model_file import read_manifest, write_model
from worker.context import JobContext
from worker.db_data import frame_data, labelled_videos
from worker.evaluation import choose_operating_point
from worker.jobs.common import (
    derived_version,
    gold_evaluation,
    model_dir,
    model_or_error,
    reload,
    started_by,
)
from worker.registration import register, store_path


def run(context: JobContext) -> dict:
    params = parse(RethresholdParams, context.params)
    context.progress(0.05, "loading the model and the labelled recordings")
    with context.read() as session:
        parent = model_or_error(session, params.model_version_id)
        parent_version, mode, parent_dir = parent.version, parent.mode, model_dir(parent)
        parent_training = (parent.lineage or {}).get("training_videos")
        videos = labelled_videos(
            session, mode, None if params.video_ids else Split.TRAIN, params.video_ids
        )
        data = frame_data(session, videos, mode)
        who = started_by(session, context)
    classifier = reload(parent_dir)
    context.progress(0.3, f"choosing threshold and delay on {len(data.names)} recordings")
    threshold, delay_ms, sweep = choose_operating_point(classifier, data)
    context.log(
        f"threshold {classifier.manifest.threshold:.3f} -> {threshold:.3f}, "
        f"delay {classifier.manifest.delay_ms} -> {delay_ms} ms"
    )
    version = params.version or derived_version(parent_version, "rt", context.job_id)
    directory = store_path(context.settings.model_store_dir, version)
    if directory.exists():
        raise ValueError(f"invalid job parameter version: {version} exists in the model store")
    manifest, source = read_manifest(parent_dir)
    onnx_bytes = (source / manifest.file).read_bytes()
    # The graph was fitted on the parent's recordings and the operating point chosen on these:
    # both are training data (unknown if the parent's are).
    parent_videos = parent_training or manifest.training_recordings
    trained_on = (
        [*parent_videos, *(n for n in data.names if n not in parent_videos)]
        if parent_videos
        else None
    )
    manifest = manifest.model_copy(
        update={
            "version": version,
            "threshold": threshold,
            "delay_ms": delay_ms,
            "created": datetime.now(UTC),
            "metrics": {
                **manifest.metrics,
                "rethreshold_data_sha256": data.data_sha256,
                "training_recordings": trained_on,
            },
        }
    )
    try:
        write_model(directory, onnx_bytes, manifest)
        classifier = reload(directory)
        context.progress(0.6, "evaluating on the gold set")
        with context.read() as session:
            metrics = gold_evaluation(session, classifier, directory, mode, sweep)
        metrics["rethreshold"] = {
            "delay_sweep": sweep,
            "data_sha256": data.data_sha256,
            "videos": data.names,
        }
        with context.result() as session:
            model = register(
                session,
                directory,
                context.settings.model_store_dir,
                lineage={
                    "started_by": who,
                    "parent": parent_version,
                    "spec": manifest.name,
                    "hyperparameters": manifest.metrics.get("params"),
                    "threshold_data_sha256": data.data_sha256,
                    "training_videos": trained_on,
                    "threshold_videos": data.names,
                },
                metrics=metrics,
                job_id=context.job_id,
                created_by_id=context.created_by_id,
            )
            model_id = model.id
    except BaseException:
        shutil.rmtree(directory, ignore_errors=True)
        raise
    return {
        "summary": f"registered {version} (threshold {threshold:.3f}, delay {delay_ms} ms)",
        "model_version_id": model_id,
        "version": version,
    }
