"""Retention: apply the frame retention policy (backend/storage/retention.py) with progress;
queued by an admin (the storage page, dry run or real) or by the worker's schedule
(`backend.storage.sweeps.schedule_retention`, every retention_interval_h)."""

from __future__ import annotations

from backend.jobs.params import RetentionParams, parse
from backend.storage.retention import run_retention
from worker.context import JobContext


def run(context: JobContext) -> dict:
    params = parse(RetentionParams, context.params)
    context.progress(0.0, "loading the policy's facts (alarms, labels, splits, lineage)")
    return run_retention(
        context.factory,
        context.settings,
        dry_run=params.dry_run,
        progress=context.progress,
        job_id=context.job_id,
    )
