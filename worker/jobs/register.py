"""Register a model directory (ONNX + manifest, e.g. from `train-default`) as a candidate and
evaluate it on the gold set; it commits once, the registered model with its gold-set
figures. A job queued by a user (through the API) reads only from the model
store; the bootstrap's own job (no user) registers the shipped default model where it lies."""

from __future__ import annotations

import shutil
from pathlib import Path

from backend.jobs.params import RegisterParams, parse, register_source
from vigil.model_file import read_manifest
from worker.context import JobContext
from worker.jobs.common import gold_evaluation, reload, started_by
from worker.registration import copy_to_store, refuse_registered, register, store_path


def run(context: JobContext) -> dict:
    params = parse(RegisterParams, context.params)
    source = Path(params.path)
    if context.created_by_id is not None:  # queued by a user: the model store only
        source = register_source(params.path, context.settings.model_store_dir)
    if not source.exists():
        raise ValueError(f"invalid job parameter path: {source} does not exist")
    classifier = reload(source)  # verifies the sha256 before anything is copied
    manifest, _ = read_manifest(source)
    with context.read() as session:
        refuse_registered(session, manifest.version)
        who = started_by(session, context)
    directory = store_path(context.settings.model_store_dir, manifest.version)
    copied = not directory.exists()
    try:
        copy_to_store(source, context.settings.model_store_dir)
        context.progress(0.5, "evaluating on the gold set")
        with context.read() as session:
            metrics = gold_evaluation(session, classifier, directory, manifest.mode)
        with context.result() as session:
            model = register(
                session,
                directory,
                context.settings.model_store_dir,
                lineage={
                    "started_by": who,
                    "source": str(source),
                    "parent": None,
                    "hyperparameters": manifest.metrics.get("params"),
                },
                metrics=metrics,
                job_id=context.job_id,
                created_by_id=context.created_by_id,
            )
            model_id, version = model.id, model.version
    except BaseException:
        if copied:
            shutil.rmtree(directory, ignore_errors=True)
        raise
    return {"summary": f"registered {version}", "model_version_id": model_id, "version": version}
