"""The promotion gate: a candidate may reach robots only if it was judged on a gold set
(recordings with split 'test') none of whose recordings it was trained on, misses no fall there,
stays within the false-alarm budget, and meets the per-frame latency bound. The report records
every figure the decision was made on."""

from __future__ import annotations

from backend.models._types import utcnow
from backend.models.registry import ModelVersion


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
        checks.append(_split_check(model, gold))
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
        "split": split_figures(model, gold),
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


def training_recordings(model: ModelVersion) -> list[str] | None:
    """The recordings the model was trained on, as registered (its lineage, from its manifest or
    the job that trained it); None when nothing records them."""
    names = (model.lineage or {}).get("training_videos")
    if not names:
        names = ((model.manifest or {}).get("metrics") or {}).get("training_recordings")
    return list(names) if names else None


def split_figures(model: ModelVersion, gold: dict | None) -> dict | None:
    """How the gold set the figures come from relates to the model's training recordings: how
    many recordings each holds and which gold recordings it was trained on (None: unknown)."""
    if not gold:
        return None
    trained_on = training_recordings(model)
    judged_on = list(gold.get("sequences") or [])
    return {
        "gold_recordings": len(judged_on),
        "training_recordings": None if trained_on is None else len(trained_on),
        "overlap": None if trained_on is None else sorted(set(trained_on) & set(judged_on)),
    }


def _split_check(model: ModelVersion, gold: dict) -> dict:
    """The gold-set figures must come from recordings the model was not trained on. A model with
    no record of its training recordings (made elsewhere and registered from a directory)
    cannot show that, so it is refused too: its figures may be its training figures."""
    split = split_figures(model, gold) or {}
    name = "judged on gold recordings it was not trained on"
    n = split["gold_recordings"]
    if split["overlap"] is None:
        return {
            "name": name,
            "passed": False,
            "value": None,
            "limit": 0,
            "detail": "training recordings unknown: nothing records what the model was trained "
            "on, so its gold-set figures may come from its training data; train it with "
            "Vigil's training (train-default, a retrain job) or record them in its manifest "
            "(training_recordings)",
        }
    overlap = split["overlap"]
    return {
        "name": name,
        "passed": not overlap,
        "value": len(overlap),
        "limit": 0,
        "detail": (
            f"{len(overlap)} of {n} gold recordings were also training data: {', '.join(overlap)}"
            if overlap
            else f"none of the {n} gold recordings is among its "
            f"{split['training_recordings']} training recordings"
        ),
    }


def _warnings(model: ModelVersion, gold: dict | None) -> list[str]:
    """What makes the figures less trustworthy (shown with the decision, not blocking it)."""
    warnings = []
    if gold and gold.get("generated_data"):
        warnings.append("the gold set includes GENERATED recordings")
    return warnings
