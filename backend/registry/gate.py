"""The promotion gate: a candidate may reach robots only if, on the gold set (recordings with
split 'test'), it misses no fall, stays within the false-alarm budget, and meets the per-frame
latency bound. The report records every figure the decision was made on."""

from __future__ import annotations

from backend.models._types import utcnow
from backend.models.registry import ModelVersion
from vigil.datasets import urfd


def gate_report(model: ModelVersion, false_alarm_budget: float, latency_ms: float) -> dict:
    gold = (model.metrics or {}).get("gold")
    latency = (model.metrics or {}).get("latency")
    checks = []
    if not gold:
        checks.append(
            {
                "name": "evaluated on the gold set",
                "passed": False,
                "value": None,
                "limit": None,
                "detail": "no gold-set evaluation: run an evaluate job first",
            }
        )
    else:
        falls, detected = gold.get("falls_total", 0), gold.get("falls_detected", 0)
        missed = [e["sequence"] for e in gold.get("events", []) if e.get("detected") is False]
        checks.append(
            {
                "name": "misses no fall of the gold set",
                "passed": falls > 0 and detected == falls,
                "value": detected,
                "limit": falls,
                "detail": (
                    "gold set holds no fall"
                    if falls == 0
                    else f"{detected} of {falls} falls detected"
                    + (f"; missed: {', '.join(missed)}" if missed else "")
                ),
            }
        )
        adl_total, adl_false = gold.get("adl_total", 0), gold.get("adl_false_alarms", 0)
        share = adl_false / adl_total if adl_total else 0.0
        checks.append(
            {
                "name": "within the false-alarm budget",
                "passed": share <= false_alarm_budget + 1e-12,
                "value": share,
                "limit": false_alarm_budget,
                "detail": (
                    f"{adl_false} of {adl_total} daily-activity recordings raised a false alarm"
                ),
            }
        )
    if not latency:
        checks.append(
            {
                "name": "per-frame latency",
                "passed": False,
                "value": None,
                "limit": latency_ms,
                "detail": "latency not measured: run an evaluate job first",
            }
        )
    else:
        checks.append(
            {
                "name": "per-frame latency",
                "passed": latency["p95_ms"] <= latency_ms,
                "value": latency["p95_ms"],
                "limit": latency_ms,
                "detail": f"p95 {latency['p95_ms']:.2f} ms over {latency['frames']} frames",
            }
        )
    return {
        "model_version": model.version,
        "passed": all(c["passed"] for c in checks),
        "checks": checks,
        "warnings": _warnings(model, gold),
        "gold": {
            k: gold.get(k)
            for k in (
                "falls_detected",
                "falls_total",
                "adl_false_alarms",
                "adl_total",
                "frame_recall",
                "frame_f1",
                "median_time_to_alarm_s",
                "data_sha256",
                "threshold",
                "delay_ms",
            )
        }
        if gold
        else None,
        "latency": latency,
        "evaluated_at": utcnow().isoformat(),
    }


def _warnings(model: ModelVersion, gold: dict | None) -> list[str]:
    """What makes the figures less trustworthy (shown with the decision, not blocking it)."""
    warnings = []
    if not gold:
        return warnings
    trained_on = set((model.lineage or {}).get("training_videos") or [])
    overlap = sorted(trained_on & set(gold.get("sequences") or []))
    if overlap:
        warnings.append(f"gold recordings were also training data: {', '.join(overlap)}")
    elif not trained_on:
        urfd_gold = any(name in urfd.NAMES for name in gold.get("sequences") or [])
        warnings.append(
            "training recordings unknown (model registered from a directory): the gold set may "
            "overlap its training data"
            + ("; e.g. train-default trains on every URFD recording" if urfd_gold else "")
        )
    if gold.get("generated_data"):
        warnings.append("the gold set includes GENERATED recordings")
    return warnings
