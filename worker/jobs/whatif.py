"""What-if: replay labelled recordings through a model at another threshold and delay and show
how alarms, recall and time to alarm would change, before anything is promoted."""

from __future__ import annotations

from backend.jobs.params import WhatIfParams, parse
from worker.context import JobContext
from worker.db_data import frame_data, labelled_videos
from worker.evaluation import evaluate_model
from worker.jobs.common import model_dir, model_or_error, reload

KEYS = (
    "falls_detected",
    "falls_total",
    "adl_false_alarms",
    "adl_total",
    "frame_recall",
    "frame_precision",
    "frame_f1",
    "median_time_to_alarm_s",
    "max_time_to_alarm_s",
)


def _summary(result: dict) -> dict:
    out = {k: result.get(k) for k in KEYS}
    out["alarms"] = sum(e["alarms"] for e in result["events"])
    out["threshold"], out["delay_ms"] = result["threshold"], result["delay_ms"]
    return out


def run(context: JobContext) -> dict:
    params = parse(WhatIfParams, context.params)
    with context.read() as session:
        model = model_or_error(session, params.model_version_id)
        directory, mode, version = model_dir(model), model.mode, model.version
        videos = labelled_videos(
            session, mode, None if params.video_ids else params.split, params.video_ids
        )
        data = frame_data(session, videos, mode)
    classifier = reload(directory)
    context.progress(0.3, f"replaying {len(data.names)} recordings")
    base = evaluate_model(classifier, data)
    new = evaluate_model(classifier, data, params.threshold, params.delay_ms)
    baseline, candidate = _summary(base), _summary(new)
    change = {
        k: (candidate[k] - baseline[k])
        if isinstance(candidate[k], int | float) and isinstance(baseline[k], int | float)
        else None
        for k in (*KEYS, "alarms")
    }
    events = [
        {
            "sequence": a["sequence"],
            "kind": a["kind"],
            "baseline": {k: a[k] for k in ("alarms", "detected", "time_to_alarm_s")},
            "candidate": {k: b[k] for k in ("alarms", "detected", "time_to_alarm_s")},
        }
        for a, b in zip(base["events"], new["events"], strict=True)
    ]
    return {
        "summary": f"{version} at threshold {params.threshold:.3f}, delay {params.delay_ms} ms: "
        f"alarms {baseline['alarms']} -> {candidate['alarms']}, falls "
        f"{baseline['falls_detected']} -> {candidate['falls_detected']}/{baseline['falls_total']}",
        "model_version_id": params.model_version_id,
        "recordings": data.names,
        "baseline": baseline,
        "candidate": candidate,
        "change": change,
        "events": events,
    }
