"""Evaluate a registered model on the gold set (recordings with split 'test'): Table 3 columns,
per-event results, per-frame latency and plots, stored with the model."""

from __future__ import annotations

from backend.jobs.params import EvaluateParams, parse
from worker.context import JobContext
from worker.jobs.common import gold_evaluation, model_dir, model_or_error, reload


def run(context: JobContext) -> dict:
    params = parse(EvaluateParams, context.params)
    with context.read() as session:
        model = model_or_error(session, params.model_version_id)
        directory, mode, version = model_dir(model), model.mode, model.version
    classifier = reload(directory)  # verifies the sha256 of the stored file
    context.progress(0.2, f"evaluating {version} on the gold set")
    with context.result() as session:
        metrics = gold_evaluation(session, classifier, directory, mode)
        if metrics.get("gold") is None:
            raise ValueError(metrics["gold_note"])
        model = model_or_error(session, params.model_version_id)
        model.metrics = {**(model.metrics or {}), **metrics}
    gold = metrics["gold"]
    return {
        "summary": f"{version}: {gold['falls_detected']}/{gold['falls_total']} falls, "
        f"{gold['adl_false_alarms']}/{gold['adl_total']} false alarms, "
        f"p95 {metrics['latency']['p95_ms']:.2f} ms/frame",
        "model_version_id": params.model_version_id,
    }
