"""Evaluate a model file on recordings: every recording replayed through the robot's frame path
(tracker, depth, floor measures, streaming features, the exported ONNX graph, threshold and
delay: worker.training.robot_path), the detection code's Table 3 / per-event evaluation,
per-frame latency, and PNG plots. The promotion gate reads these figures."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from vigil.classes import Decision
from vigil.model_file import Classifier, load_classifier
from vigil.runtime import FrameClassifier
from vigil.skeleton import SkeletonFrame
from worker.training.data import FrameData
from worker.training.robot_path import replay_stream
from worker.training.selection import (
    StreamScores,
    choose_delay,
    choose_threshold,
    evaluate,
)

LATENCY_FRAMES = 300


class _AtOperatingPoint:
    """A model with another threshold and delay (a what-if): same graph, other manifest."""

    def __init__(self, classifier: Classifier, threshold: float, delay_ms: int) -> None:
        self._classifier = classifier
        self.manifest = classifier.manifest.model_copy(
            update={"threshold": float(threshold), "delay_ms": int(delay_ms)}
        )

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        return self._classifier.predict_proba(features)


def score_stream(
    classifier: Classifier, data: FrameData, threshold=None, delay_ms=None
) -> StreamScores:
    """Scores and decisions of every frame of every sequence through the robot's path."""
    manifest = classifier.manifest
    if threshold is not None or delay_ms is not None:
        classifier = _AtOperatingPoint(
            classifier,
            manifest.threshold if threshold is None else threshold,
            manifest.delay_ms if delay_ms is None else delay_ms,
        )
    stream, _, _ = replay_stream(FrameClassifier(classifier), data)
    return stream


def evaluate_model(classifier: Classifier, data: FrameData, threshold=None, delay_ms=None) -> dict:
    """Table 3 columns and per-event results at the model's (or the given) operating point."""
    t = classifier.manifest.threshold if threshold is None else threshold
    d = classifier.manifest.delay_ms if delay_ms is None else delay_ms
    stream = score_stream(classifier, data, t, d)
    result = evaluate(stream, float(t), d / 1000.0)
    result["threshold"], result["delay_ms"] = float(t), int(d)
    result["frames"] = int(len(data.target))
    result["sequences"] = list(data.names)
    result["data_sha256"] = data.data_sha256
    result["generated_data"] = bool(data.generated)
    result["inputs"] = list(classifier.manifest.inputs)
    return result


def choose_operating_point(classifier: Classifier, data: FrameData) -> tuple[float, int, dict]:
    """Re-choose threshold (Youden / micro-F1) and delay (event F1) of a fixed model on new data."""
    stream = score_stream(classifier, data)
    labelled = data.target >= 0
    threshold = choose_threshold(stream.scores[labelled], data.target[labelled], data.classes)
    delay_s, sweep = choose_delay(stream, threshold)
    return threshold, int(round(delay_s * 1000)), sweep


def measure_latency(model_dir: Path, data: FrameData | None = None, n: int = LATENCY_FRAMES):
    """Per-frame time of the robot's runtime (features + ONNX + policy), one frame at a time."""
    runtime = FrameClassifier.from_dir(model_dir)
    rng = np.random.default_rng(0)
    frames = []
    for i in range(n):
        keypoints = np.zeros((25, 3), np.float32)
        keypoints[:, :2] = rng.uniform(100, 400, (25, 2))
        keypoints[:, 2] = 0.9
        floor = [rng.uniform(0.2, 1.8), rng.uniform(0.1, 1.0), rng.uniform(0, 1)]
        frames.append(SkeletonFrame(keypoints=keypoints, timestamp=i / 30.0, floor=floor))
    for frame in frames[:20]:  # warm-up
        runtime.classify(frame)
    runtime.reset()
    times = []
    for frame in frames:
        start = time.perf_counter()
        runtime.classify(frame)
        times.append((time.perf_counter() - start) * 1000)
    times = np.array(times)
    return {
        "frames": n,
        "p50_ms": float(np.percentile(times, 50)),
        "p95_ms": float(np.percentile(times, 95)),
        "max_ms": float(times.max()),
        "note": "features + ONNX + policy per frame, synthetic poses, 1 thread",
    }


def write_plots(
    classifier: Classifier, data: FrameData, result: dict, out_dir: Path, sweep: dict | None = None
) -> list[str]:
    """The detection code's ROC / precision-recall (default and chosen threshold) and delay-sweep
    plots, plus time to alarm per gold fall; returns the plot names written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from worker.training import plots

    out_dir.mkdir(parents=True, exist_ok=True)
    stream = score_stream(classifier, data)
    e = data.classes.index(Decision.EMERGENCY)
    labelled = data.target >= 0
    truth = data.target[labelled] == e
    manifest = classifier.manifest
    written = []
    if truth.any() and (~truth).any():
        plots.roc_pr(
            stream.scores[labelled, e],
            truth,
            manifest.threshold,
            f"{manifest.version}: Emergency frames of the gold set",
            out_dir / "roc_pr.png",
        )
        written.append("roc_pr")
    if sweep is not None:
        plots.delay_metrics(
            sweep,
            manifest.delay_ms / 1000,
            f"{manifest.version}: delay chosen on training predictions",
            out_dir / "delay.png",
        )
        written.append("delay")
    falls = [ev for ev in result.get("events", []) if ev["kind"] == "fall"]
    if falls:
        fig, ax = plt.subplots(figsize=(6, max(2.5, 0.22 * len(falls))), dpi=90)
        names = [ev["sequence"] for ev in falls]
        values = [ev["time_to_alarm_s"] if ev["detected"] else 0.0 for ev in falls]
        colors = ["tab:blue" if ev["detected"] else "tab:red" for ev in falls]
        ax.barh(names, values, color=colors)
        for i, ev in enumerate(falls):
            if not ev["detected"]:
                ax.text(0, i, " missed", va="center", color="tab:red")
        ax.set(xlabel="time to alarm (s)", title="Falls of the gold set")
        fig.tight_layout()
        fig.savefig(out_dir / "time_to_alarm.png")
        plt.close(fig)
        written.append("time_to_alarm")
    return written


def load(model_dir: Path) -> Classifier:
    return load_classifier(model_dir)
