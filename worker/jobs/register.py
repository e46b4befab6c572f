"""Register a model directory (ONNX + manifest, e.g. from `train-default`) as a candidate and
evaluate it on the gold set. A job queued by a user (through the API) reads only from the model
store; the bootstrap's own job (no user) registers the shipped default model where it lies."""

from __future__ import annotations

from pathlib import Path

from backend.db import transaction
from backend.jobs.params import RegisterParams, parse, register_source
from vigil.model_file import read_manifest
from worker.context import JobContext
from worker.jobs.common import gold_evaluation, reload, started_by
from worker.registration import register, store_path


def run(context: JobContext) -> dict:
    params = parse(RegisterParams, context.params)
    source = Path(params.path)
    if context.created_by_id is not None:  # queued by a user: the model store only
        source = register_source(params.path, context.settings.model_store_dir)
    if not source.exists():
        raise ValueError(f"invalid job parameter path: {source} does not exist")
    classifier = reload(source)  # verifies the sha256 before anything is copied
    manifest, _ = read_manifest(source)
    with transaction(context.factory) as session:
        who = started_by(session, context)
        model = register(session, source, context.settings.model_store_dir,
                         lineage={"started_by": who, "source": str(source), "parent": None,
                                  "hyperparameters": manifest.metrics.get("params")},
                         job_id=context.job_id, created_by_id=context.created_by_id)  # fmt: skip
        model_id, version = model.id, model.version
    context.progress(0.5, "evaluating on the gold set")
    directory = store_path(context.settings.model_store_dir, version)
    with transaction(context.factory) as session:
        metrics = gold_evaluation(session, classifier, directory, manifest.mode)
        session.get(type(model), model_id).metrics = metrics
    return {"summary": f"registered {version}", "model_version_id": model_id, "version": version}
