"""How much the detection figures depend on the split, on REAL data (URFD):
`python -m bench.detection_splits` (make bench-detection-splits) writes
bench/results/detection_urfd_splits.json.

`make bench-detection` splits URFD's 70 sequences into five folds once (seed 0). This runs the
same nested cross-validation (grid, threshold and delay chosen on the training folds only, the
same inner folds and stride as the training job) for the best model over several seeds of that
split, and reports every split's results next to each other. With 30 falls and 40 daily
activities, one sequence is 2.5 % of a goal: which sequences share a fold moves the figures.

It also pools the held-out scores of all splits into an operating curve: falls detected, false
alarms, median time to alarm and frame recall at fixed thresholds and delays, nothing chosen. That
separates what the model can do from how well the training folds choose its operating point.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from vigil.features import FEATURE_VERSION
from worker.training.cli import make_trainers
from worker.training.cross_validation import cross_validate
from worker.training.data import concatenate, from_urfd, with_emergency_lead
from worker.training.generated import LOOK_ALIKE_EVENTS
from worker.training.generated import hard_negatives as generated_hard_negatives
from worker.training.run import INNER_FOLDS, TRAIN_STRIDE
from worker.training.selection import CURVE_KEYS, StreamScores, operating_curve

RESULTS = Path(__file__).resolve().parent / "results" / "detection_urfd_splits.json"
FOLDS = 5
SPLIT_KEYS = (*CURVE_KEYS, "fold_operating_points")
CURVE_THRESHOLDS = (0.1, 0.2, 0.3, 0.4, 0.5)
CURVE_DELAYS_S = tuple(round(0.05 * k, 2) for k in range(2, 17))  # 0.1 .. 0.8 s


def _one_split(
    model: str, seed: int, urfd_dir: Path | None, lead_s: float, hard_negatives: int = 0
) -> dict:
    with threadpool_limits(limits=1):
        data = from_urfd(urfd_dir)
        train_only = None
        if hard_negatives:
            urfd_sequences = len(data.names)
            data = concatenate(data, generated_hard_negatives(repeats=hard_negatives))
            train_only = np.arange(urfd_sequences, len(data.names))
        if lead_s:
            data = with_emergency_lead(data, lead_s)
        cv = cross_validate(
            make_trainers([model])[0],
            data,
            FOLDS,
            INNER_FOLDS,
            TRAIN_STRIDE,
            seed=seed,
            train_only=train_only,
        )
    return {
        "seed": seed,
        **{key: cv.result[key] for key in SPLIT_KEYS},
        "events": [
            {key: event[key] for key in ("sequence", "kind", "false_alarm", "time_to_alarm_s")}
            for event in cv.result["events"]
        ],
        "seconds": round(cv.seconds, 1),
        "test_scores": [(s.sequences, s.scores) for s in cv.test_scores],
    }


def measure(
    model: str = "gbt",
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4),
    urfd_dir: Path | None = None,
    workers: int = 2,
    emergency_lead_s: float = 0.0,
    hard_negatives: int = 0,
) -> dict:
    start = time.perf_counter()
    n = len(seeds)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        splits = list(
            pool.map(
                _one_split,
                [model] * n,
                seeds,
                [urfd_dir] * n,
                [emergency_lead_s] * n,
                [hard_negatives] * n,
            )
        )
    data = from_urfd(urfd_dir)
    streams = [
        StreamScores(data, sequences, scores)
        for split in splits
        for sequences, scores in split.pop("test_scores")
    ]
    curve = operating_curve(streams, CURVE_THRESHOLDS, CURVE_DELAYS_S)
    per_sequence = _per_sequence(splits)
    adl = [s["adl_false_alarms"] for s in splits]
    tta = [s["median_time_to_alarm_s"] for s in splits]
    recall = [s["frame_recall"] for s in splits]
    return {
        "data": "REAL: URFD, 30 falls and 40 daily activities",
        # Training rows made on the robot's frame path (vigil.detector.stream_features).
        "training_frames": "robot_path",
        "model": model,
        "feature_version": FEATURE_VERSION,
        "folds": FOLDS,
        "inner_folds": INNER_FOLDS,
        # Models fitted to Emergency starting this much before the labelled frames (evaluation,
        # thresholds and delays on the labels): worker.training.data.with_emergency_lead.
        "emergency_lead_s": emergency_lead_s,
        # GENERATED look-alike transports added to every training fold, never scored
        # (worker.training.generated.hard_negatives): this many per event.
        "hard_negatives": (
            {"generated": True, "events": list(LOOK_ALIKE_EVENTS), "per_event": hard_negatives}
            if hard_negatives
            else None
        ),
        "seeds": list(seeds),
        "splits": splits,
        "summary": {
            "falls_detected_min": min(s["falls_detected"] for s in splits),
            "adl_false_alarms_min": min(adl),
            "adl_false_alarms_max": max(adl),
            "median_time_to_alarm_s_min": min(tta),
            "median_time_to_alarm_s_max": max(tta),
            "frame_recall_min": min(recall),
            "frame_recall_max": max(recall),
        },
        "per_sequence": per_sequence,
        "operating_curve": {
            "pooled_splits": len(splits),
            "falls_total": curve[0]["falls_total"],
            "adl_total": curve[0]["adl_total"],
            "points": curve,
        },
        "seconds": round(time.perf_counter() - start, 1),
        "machine": {"cpus": os.cpu_count(), "workers": workers},
    }


def _per_sequence(splits: list[dict]) -> dict:
    """Which sequences the figures come from: per daily activity, the splits in which it raised a
    false alarm; per fall, its time to alarm in every split (None: missed)."""
    adl: dict[str, int] = {}
    falls: dict[str, list[float | None]] = {}
    for split in splits:
        for event in split["events"]:
            if event["kind"] == "adl":
                adl[event["sequence"]] = adl.get(event["sequence"], 0) + event["false_alarm"]
            else:
                falls.setdefault(event["sequence"], []).append(event["time_to_alarm_s"])
    return {
        "adl_false_alarm_splits": {name: n for name, n in sorted(adl.items()) if n},
        "fall_time_to_alarm_s": dict(sorted(falls.items())),
    }


def _seconds(value: float | None) -> str:
    return "–" if value is None else f"{value:.2f}"


def markdown_tables(result: dict) -> str:
    """The tables of docs/detection.md, generated from detection_urfd_splits.json."""
    lines = [
        "| split seed | frame recall | frame F1 | falls detected "
        "| ADL sequences with a false alarm | median time to alarm (s) "
        "| thresholds / delays (ms) chosen in the folds |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in result["splits"]:
        points = s["fold_operating_points"]
        chosen = ", ".join(f"{p['threshold']:g}/{p['delay_ms']}" for p in points)
        lines.append(
            f"| {s['seed']} | {s['frame_recall']:.3f} | {s['frame_f1']:.3f} "
            f"| {s['falls_detected']}/{s['falls_total']} "
            f"| {s['adl_false_alarms']}/{s['adl_total']} "
            f"| {_seconds(s['median_time_to_alarm_s'])} | {chosen} |"
        )
    curve = result["operating_curve"]
    points = {(p["threshold"], p["delay_ms"]): p for p in curve["points"]}
    thresholds = sorted({p["threshold"] for p in curve["points"]})
    delays = sorted({p["delay_ms"] for p in curve["points"]})
    lines += [
        "",
        f"Pooled held-out scores of {curve['pooled_splits']} splits ({curve['falls_total']} fall "
        f"and {curve['adl_total']} daily-activity sequences) at fixed operating points; each cell: "
        "falls detected, daily-activity sequences with a false alarm, median time to alarm (s).",
        "",
        "| delay (ms) | " + " | ".join(f"threshold {t:g}" for t in thresholds) + " |",
        "|---|" + "---|" * len(thresholds),
        "| frame recall | "
        + " | ".join(f"{points[t, delays[0]]['frame_recall']:.3f}" for t in thresholds)
        + " |",
    ]
    for d in delays:
        cells = [
            f"{p['falls_detected']}, {p['adl_false_alarms']}, "
            + _seconds(p["median_time_to_alarm_s"])
            for p in (points[t, d] for t in thresholds)
        ]
        lines.append(f"| {d} | " + " | ".join(cells) + " |")
    per_sequence = result.get("per_sequence")
    if per_sequence:
        n = len(result["splits"])
        alarming = per_sequence["adl_false_alarm_splits"]
        lines += [
            "",
            f"Daily-activity sequences with a false alarm (in how many of the {n} splits): "
            + (", ".join(f"{name} ({k})" for name, k in alarming.items()) or "none")
            + ".",
        ]
        slow = {
            name: float(np.median([np.inf if t is None else t for t in times]))
            for name, times in per_sequence["fall_time_to_alarm_s"].items()
        }
        slow = {name: t for name, t in sorted(slow.items(), key=lambda kv: -kv[1]) if t > 0.5}
        lines += [
            "",
            "Falls whose median time to alarm over the splits is above 0.5 s (s; inf: missed in "
            "most splits): "
            + (", ".join(f"{name} ({t:.2f})" for name, t in slow.items()) or "none")
            + ".",
        ]
    return "\n".join(lines) + "\n"


def best_model(results: Path = RESULTS.with_name("detection_urfd.json")) -> str:
    """The model `make bench-detection` found best (gbt when it has not run)."""
    if not results.exists():
        return "gbt"
    return json.loads(results.read_text()).get("best") or "gbt"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--model",
        default=None,
        help="default: the best model of bench/results/detection_urfd.json (make bench-detection)",
    )
    parser.add_argument("--seeds", default="0,1,2,3,4", help="comma-separated split seeds")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--urfd-dir", type=Path, default=None)
    parser.add_argument(
        "--emergency-lead-s",
        type=float,
        default=0.0,
        help="fit the models to Emergency starting this many seconds before the labelled frames",
    )
    parser.add_argument(
        "--hard-negatives",
        type=int,
        default=0,
        help="GENERATED look-alike transports per event added to every training fold, unscored",
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument(
        "--table", action="store_true", help="only print the Markdown tables of an existing --out"
    )
    args = parser.parse_args(argv)
    if args.model is None:
        args.model = best_model()
    if args.table:
        print(markdown_tables(json.loads(args.out.read_text())), end="")
        return 0
    try:
        seeds = tuple(int(s) for s in args.seeds.split(","))
    except ValueError:
        parser.error(f"--seeds: expected comma-separated integers, got {args.seeds!r}")
    try:
        make_trainers([args.model])
    except ValueError as error:
        parser.error(str(error).replace("--models", "--model"))
    if not args.emergency_lead_s >= 0:
        parser.error(f"--emergency-lead-s: must be >= 0, got {args.emergency_lead_s}")
    if args.hard_negatives < 0:
        parser.error(f"--hard-negatives: must be >= 0, got {args.hard_negatives}")
    result = measure(
        args.model,
        seeds,
        args.urfd_dir,
        args.workers,
        args.emergency_lead_s,
        args.hard_negatives,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=_jsonable) + "\n")
    print(json.dumps({k: result[k] for k in ("model", "seeds", "summary", "seconds")}, indent=2))
    return 0


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


if __name__ == "__main__":
    raise SystemExit(main())
