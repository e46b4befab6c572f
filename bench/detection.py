"""Detection benchmark on real falls (URFD): `python -m bench.detection` (make bench-detection).

Runs the full training job (grouped 5-fold cross-validation of every model with grids, thresholds
and delays chosen on training folds only, then a retrain of every model on all data with ONNX
export). Every held-out recording is replayed through the robot's own frame path (URFD replay
observations -> tracker -> floor measures -> streaming features -> each fold's exported ONNX
model -> threshold and delay filter: vigil.detector), which gives each model's `robot_path`
figures, the ones of record; the direct figures (bulk features, the same models) stay beside them.
Per-frame latency is measured through the same path (tracker + features + ONNX Runtime +
policy). Writes bench/results/detection_urfd.json plus the full report next to it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from vigil.datasets import urfd
from vigil.detector import Detector, patient_stream
from vigil.events import SequenceEvent, summarise
from vigil.features import FEATURE_VERSION
from vigil.policy import (
    LOST_FALL_SPEED,
    LOST_FALL_WINDOW_S,
    LOST_WHILE_FALLING,
    LostWhileFalling,
)
from vigil.runtime import FrameClassifier
from worker.training.cli import ALL_MODELS, make_trainers
from worker.training.data import from_urfd
from worker.training.run import train_all

RESULTS = Path(__file__).resolve().parent / "results"
SCHEMA_KEYS = (
    "name",
    "frame_recall",
    "frame_f1",
    "falls_detected",
    "falls_total",
    "adl_false_alarms",
    "adl_total",
    "median_time_to_alarm_s",
    "threshold",
    "delay_ms",
)
# Beyond the schema: where in the falls the missed Emergency frames are, what the model
# needs in every frame, and its figures through the robot's frame path.
EXTRA_KEYS = ("recall_by_onset", "inputs", "robot_path")
ROBOT_PATH_KEYS = (
    "falls_detected",
    "falls_total",
    "adl_false_alarms",
    "adl_total",
    "frame_recall",
    "frame_f1",
    "median_time_to_alarm_s",
    "tracker_dropped_frames",
    "tracker_refused_implausible_frames",
    "recall_by_onset",
)


def frame_latency_ms(model_dir: Path, sequences) -> dict:
    """Per-frame latency of the robot's frame path (vigil.detector: tracker, floor measures,
    features, ONNX Runtime inference, policy) over every URFD frame, streamed sequence by
    sequence.

    Wall-clock figures include waiting for a core on a loaded machine; `cpu_*` figures are the
    thread's own CPU time per frame."""
    detector = Detector(FrameClassifier.from_dir(model_dir))
    wall, cpu = [], []
    for seq in sequences:
        detector.reset()
        for observation in seq.observations():
            start, start_cpu = time.perf_counter(), time.thread_time()
            detector.process(observation)
            cpu.append(time.thread_time() - start_cpu)
            wall.append(time.perf_counter() - start)
    ms, cpu_ms = np.array(wall) * 1000, np.array(cpu) * 1000
    return {
        "frames": len(ms),
        "p50": float(np.percentile(ms, 50)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
        "cpu_p50": float(np.percentile(cpu_ms, 50)),
        "cpu_p99": float(np.percentile(cpu_ms, 99)),
        "load_average_1min": os.getloadavg()[0],
    }


def lost_while_falling_figures(sequences) -> dict:
    """The frame path's lost-while-falling rule benchmarked like a model, on its own: every URFD
    recording through the patient tracker (vigil.detector.patient_stream) and the rule; an alarm
    is the rule turning Emergency, scored with the binding event definitions (vigil.events).
    In every model's robot_path figures the rule runs beside the model."""
    events = []
    for seq in sequences:
        frames, seen = patient_stream(seq.observations())
        rule = LostWhileFalling()
        fired = np.array([rule.update(f, s) for f, s in zip(frames, seen, strict=True)], bool)
        turned = fired & ~np.r_[False, fired[:-1]]
        alarms = tuple(float(t) for t in seq.timestamps[turned])
        events.append(SequenceEvent(seq.name, seq.is_fall, seq.first_emergency_time(), alarms))
    summary = summarise(events)
    return {
        "name": LOST_WHILE_FALLING,
        "speed_torso_lengths_per_s": LOST_FALL_SPEED,
        "window_s": LOST_FALL_WINDOW_S,
        **{
            k: summary[k]
            for k in (
                "falls_detected",
                "falls_total",
                "adl_false_alarms",
                "adl_total",
                "median_time_to_alarm_s",
                "max_time_to_alarm_s",
            )
        },
        "falls_fired": sorted(e.name for e in events if e.positive and e.detected),
        "adl_fired": sorted(e.name for e in events if not e.positive and e.false_alarm),
    }


def markdown_table(result: dict) -> str:
    """The results table of docs/detection.md, generated from detection_urfd.json: the robot
    path's figures, and the direct ones beside them."""
    header = (
        "| model | inputs | frame recall | frame F1 | falls detected "
        "| ADL sequences with a false alarm | median time to alarm (s) | tracker dropped frames "
        "| refused as implausible "
        "| direct: recall / F1 / falls / ADL / time | threshold | delay (ms) |"
    )
    lines = [header, "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in result["models"]:
        rp = m.get("robot_path") or {}
        best = " (best)" if m["name"] == result["best"] else ""
        best += " (best keypoints-only)" if m["name"] == result.get("best_keypoints_only") else ""
        lines.append(
            f"| {m['name']}{best} | {', '.join(m.get('inputs', []))} "
            f"| {_f(rp.get('frame_recall'))} | {_f(rp.get('frame_f1'))} "
            f"| {rp.get('falls_detected', '-')}/{rp.get('falls_total', '-')} "
            f"| {rp.get('adl_false_alarms', '-')}/{rp.get('adl_total', '-')} "
            f"| {_f(rp.get('median_time_to_alarm_s'), 2)} "
            f"| {rp.get('tracker_dropped_frames', '-')} "
            f"| {rp.get('tracker_refused_implausible_frames', '-')} "
            f"| {_f(m['frame_recall'])} / {_f(m['frame_f1'])} / "
            f"{m['falls_detected']}/{m['falls_total']} / {m['adl_false_alarms']}/{m['adl_total']} "
            f"/ {_f(m['median_time_to_alarm_s'], 2)} "
            f"| {m['threshold']:.3f} | {m['delay_ms']} |"
        )
    return "\n".join(lines) + "\n"


def _f(value, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def model_entry(row: dict) -> dict:
    entry = {key: row[key] for key in (*SCHEMA_KEYS, *EXTRA_KEYS)}
    entry["robot_path"] = {key: row["robot_path"][key] for key in ROBOT_PATH_KEYS}
    return entry


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default=ALL_MODELS)
    parser.add_argument("--out", type=Path, default=RESULTS / "detection_urfd.json")
    parser.add_argument("--urfd-dir", type=Path, default=None)
    parser.add_argument(
        "--table", action="store_true", help="only print the Markdown table of an existing --out"
    )
    parser.add_argument(
        "--latency-only",
        action="store_true",
        help="re-measure per-frame latency of the models of an existing run",
    )
    args = parser.parse_args(argv)
    if args.table:
        print(markdown_table(json.loads(args.out.read_text())), end="")
        return 0
    if args.latency_only:
        result = json.loads(args.out.read_text())
        report_dir = args.out.with_suffix("")
        sequences = urfd.load(args.urfd_dir)
        result["frame_latency_ms"] = {
            m["name"]: frame_latency_ms(report_dir / "models" / m["name"], sequences)
            for m in result["models"]
        }
        result["p99_frame_ms"] = result["frame_latency_ms"][result["best"]]["p99"]
        result["p99_frame_cpu_ms"] = result["frame_latency_ms"][result["best"]]["cpu_p99"]
        args.out.write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps(result["frame_latency_ms"], indent=2))
        return 0

    data = from_urfd(args.urfd_dir)
    report_dir = args.out.with_suffix("")  # bench/results/detection_urfd/
    report = train_all(data, make_trainers(args.models.split(",")), report_dir, n_folds=5)
    sequences = urfd.load(args.urfd_dir)
    latency = {
        row["name"]: frame_latency_ms(Path(row["model_dir"]), sequences) for row in report["models"]
    }
    result = {
        "dataset": "urfd",
        "feature_version": FEATURE_VERSION,
        "folds": report["folds"],
        "best": report["best"],
        "best_keypoints_only": report["best_keypoints_only"],
        "models": [model_entry(row) for row in report["models"]],
        "retrain_s": round(report["retrain_s"], 1),
        "cross_validation_s": round(report["evaluation_s"], 1),
        "frames": report["frames"],
        "p99_frame_ms": latency[report["best"]]["p99"],
        "p99_frame_cpu_ms": latency[report["best"]]["cpu_p99"],
        "frame_latency_ms": latency,
        "rules": [lost_while_falling_figures(sequences)],
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "load_average_1min_at_end": os.getloadavg()[0],
        },
        "report": str(report_dir.relative_to(RESULTS.parent.parent))
        if report_dir.is_relative_to(RESULTS.parent.parent)
        else str(report_dir),
    }
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "frame_latency_ms"}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
