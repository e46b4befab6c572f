"""The whole job: evaluate every model by grouped cross-validation, retrain each on all data,
export ONNX models, write a report (JSON + Markdown, Table 3 columns and per-event results) and
PNG plots. Used by the vigil-train CLI and by bench/detection.py."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from vigil.classes import Decision
from vigil.inputs import is_keypoints_only
from worker.training.cross_validation import cross_validate, select
from worker.training.data import FrameData
from worker.training.plots import delay_metrics, roc_pr
from worker.training.publish import publish
from worker.training.robot_path import robot_path_cross_validation
from worker.training.selection import onset_bin_label
from worker.training.trainers import Trainer

TABLE_COLUMNS = (
    ("model", "name"),
    ("Recall", "frame_recall"),
    ("F1", "frame_f1"),
    ("threshold", "threshold"),
    ("delay ms", "delay_ms"),
    ("FP_d/FP", "fp_d_over_fp"),
    ("FN_d/FN", "fn_d_over_fn"),
    ("falls", "falls"),
    ("ADL false alarms", "adl"),
    ("median / max time to alarm s", "tta"),
    ("time to stable max / mean / std s", "stable"),
)


# Inner folds of the grid search and the training-frame stride of its fits (the final refit of
# every fold uses every frame).
INNER_FOLDS = 3
TRAIN_STRIDE = 3


def rank_key(row: dict) -> tuple:
    """Best model: most falls detected minus sequences with a false alarm, then frame F1, on
    the robot's frame path where it was measured."""
    figures = row.get("robot_path") or row
    return (figures["falls_detected"] - figures["adl_false_alarms"], figures["frame_f1"])


def train_all(*args, blas_threads: int = 1, **kwargs) -> dict:
    """See _train_all. BLAS runs single-threaded: on a shared 2-core machine, threaded matrix
    products in many small fits oversubscribe the cores and run many times slower."""
    with threadpool_limits(limits=blas_threads):
        return _train_all(*args, **kwargs)


def _train_all(
    data: FrameData,
    trainers: list[Trainer],
    out_dir: Path,
    n_folds: int = 5,
    n_inner: int = INNER_FOLDS,
    stride: int = TRAIN_STRIDE,
    progress: bool = True,
) -> dict:
    out_dir = Path(out_dir)
    (out_dir / "plots").mkdir(parents=True, exist_ok=True)
    e = data.classes.index(Decision.EMERGENCY)
    rows, retrain_s, evaluation_s = [], 0.0, 0.0
    total = sum(len(t.configurations()) for t in trainers) * (n_folds + 1)
    bar = tqdm(
        total=total, desc=f"{data.mode.value} grids", unit="config-fold", disable=not progress
    )
    for trainer in trainers:
        bar.set_postfix_str(trainer.name)
        cv = cross_validate(trainer, data, n_folds, n_inner, stride, progress=bar)
        evaluation_s += cv.seconds
        started = time.perf_counter()
        robot_path = (
            robot_path_cross_validation(trainer, cv, data) if data.recordings is not None else None
        )
        robot_path_s = time.perf_counter() - started
        start = time.perf_counter()
        final = select(trainer, data, np.arange(len(data.names)), n_folds, stride, progress=bar)
        manifest = publish(
            trainer,
            final,
            data,
            out_dir / "models" / trainer.name,
            metrics={k: v for k, v in cv.result.items() if k != "events"},
        )
        retrain_s += time.perf_counter() - start
        scores = np.concatenate([s.scores for s in cv.test_scores])
        target = np.concatenate([data.target[data.frames_of(s.sequences)] for s in cv.test_scores])
        labelled = target >= 0
        chosen = float(np.median([f.threshold for f in cv.folds]))
        tag = " (generated data)" if data.generated else ""
        roc_pr(
            scores[labelled, e],
            target[labelled] == e,
            chosen,
            f"{trainer.name}, {data.mode.value}: held-out folds{tag}",
            out_dir / "plots" / f"{trainer.name}_roc_pr.png",
        )
        delay_metrics(
            final.delay_sweep,
            final.delay_s,
            f"{trainer.name}, {data.mode.value}: training predictions over delay{tag}",
            out_dir / "plots" / f"{trainer.name}_delay.png",
        )
        rows.append(
            {
                "name": trainer.name,
                **cv.result,
                "threshold": manifest.threshold,
                "delay_ms": manifest.delay_ms,
                "params": manifest.metrics.get("params"),
                "fold_params": [f.params for f in cv.folds],
                "grid": final.grid_scores,
                "robot_path": robot_path,
                "inputs": manifest.inputs,
                "evaluation_s": cv.seconds,
                "robot_path_s": robot_path_s,
                "retrain_s": time.perf_counter() - start,
                "model_dir": str(out_dir / "models" / trainer.name),
            }
        )
    bar.close()
    best = max(rows, key=rank_key)["name"]
    keypoints_only = [r for r in rows if is_keypoints_only(r["inputs"])]
    best_keypoints_only = max(keypoints_only, key=rank_key)["name"] if keypoints_only else None
    report = {
        "dataset": "generated" if data.generated else "urfd",
        "generated": data.generated,
        "mode": data.mode.value,
        "folds": n_folds,
        "best": best,
        "best_keypoints_only": best_keypoints_only,
        "retrain_s": retrain_s,
        "evaluation_s": evaluation_s,
        "frames": int(len(data.target)),
        "models": rows,
    }
    (out_dir / "report.json").write_text(json.dumps(report, indent=2, default=_plain))
    (out_dir / "report.md").write_text(markdown(report))
    return report


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"not JSON: {type(value)}")


def _fmt(value, digits=3):
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def table_row(row: dict) -> list[str]:
    stable = row["time_to_stable_s"]
    return [
        row["name"],
        _fmt(row["frame_recall"]),
        _fmt(row["frame_f1"]),
        _fmt(row["threshold"]),
        str(row["delay_ms"]),
        _fmt(row["fp_d_over_fp"], 2),
        _fmt(row["fn_d_over_fn"], 2),
        f"{row['falls_detected']}/{row['falls_total']}",
        f"{row['adl_false_alarms']}/{row['adl_total']}",
        f"{_fmt(row['median_time_to_alarm_s'], 2)} / {_fmt(row['max_time_to_alarm_s'], 2)}",
        f"{_fmt(stable['max'], 2)} / {_fmt(stable['mean'], 2)} / {_fmt(stable['std'], 2)}",
    ]


def markdown(report: dict) -> str:
    generated = report["generated"]
    lines = [
        f"# Detection report: {report['mode']} mode on "
        + (
            "GENERATED data (not real; demo of the pipeline only)"
            if generated
            else "URFD (real falls)"
        ),
        "",
        f"{report['folds']}-fold cross-validation grouped by sequence; threshold and delay chosen "
        "on the training folds only. Recall and F1 are frame-level before the delay filter; the "
        "event columns use the delay-filtered alarms. Threshold and delay shown are those of the "
        "model "
        f"retrained on all data. Best: **{report['best']}**. Retrain of all models: "
        f"{report['retrain_s']:.0f} s; cross-validation: {report['evaluation_s']:.0f} s.",
        "",
        "| " + " | ".join(c for c, _ in TABLE_COLUMNS) + " |",
        "|" + "---|" * len(TABLE_COLUMNS),
    ]
    lines += ["| " + " | ".join(table_row(r)) + " |" for r in report["models"]]
    lines += ["", "## Per-event results", ""]
    for row in report["models"]:
        missed = [
            ev["sequence"] for ev in row["events"] if ev["kind"] == "fall" and not ev["detected"]
        ]
        alarms = [ev["sequence"] for ev in row["events"] if ev["false_alarm"]]
        by_onset = ", ".join(
            f"{b['missed']}/{b['emergency_frames']} {onset_bin_label(b)}"
            for b in row.get("recall_by_onset", [])
        )
        lines.append(
            f"- **{row['name']}**: missed falls: {', '.join(missed) or 'none'}; "
            f"sequences with a false alarm: {', '.join(alarms) or 'none'}; "
            f"missed Emergency frames by time since the first Emergency label: {by_onset or '-'}"
        )
    robot_rows = [r for r in report["models"] if r.get("robot_path")]
    if robot_rows:
        lines += [
            "",
            "## Through the robot's frame path",
            "",
            "Every held-out recording replayed through tracker, depth, floor measures, streaming "
            "features, ONNX Runtime and the delay filter, with each fold's exported model.",
            "",
            "| model | inputs | frame recall | frame F1 | falls | ADL false alarms "
            "| median time to alarm s | tracker dropped frames | refused as implausible |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for row in robot_rows:
            rp = row["robot_path"]
            lines.append(
                f"| {row['name']} | {', '.join(row['inputs'])} | {_fmt(rp['frame_recall'])} "
                f"| {_fmt(rp['frame_f1'])} | {rp['falls_detected']}/{rp['falls_total']} "
                f"| {rp['adl_false_alarms']}/{rp['adl_total']} "
                f"| {_fmt(rp['median_time_to_alarm_s'], 2)} | {rp['tracker_dropped_frames']} "
                f"| {rp.get('tracker_refused_implausible_frames', '-')} |"
            )
    lines += ["", "Plots: `plots/<model>_roc_pr.png`, `plots/<model>_delay.png`."]
    return "\n".join(lines) + "\n"
