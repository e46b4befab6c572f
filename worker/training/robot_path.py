"""Scores and decisions of recordings replayed through the robot's frame path (vigil.replay):
what the worker's gold-set evaluation, the promotion gate and `make bench-detection` report."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from vigil.detector import Detector
from vigil.replay import replay
from vigil.runtime import FrameClassifier
from worker.training.cross_validation import CrossValidation
from worker.training.data import FrameData
from worker.training.publish import publish
from worker.training.selection import CURVE_KEYS, StreamScores, evaluate_folds
from worker.training.trainers import Trainer

#: Per model in bench/results/detection_urfd.json and the training report.
ROBOT_PATH_KEYS = (*CURVE_KEYS, "tracker_dropped_frames", "tracker_refused_implausible_frames")


def replay_stream(
    classifier: FrameClassifier, data: FrameData, sequences: np.ndarray | None = None
) -> tuple[StreamScores, int, int]:
    """Every frame of the sequences (all by default) through tracker, depth, floor measures,
    streaming features, ONNX Runtime and the delay filter, one sequence as one stream; the
    frames where a plausible person was in view but the tracker passed on no patient; and the
    frames without the patient where it refused someone in view as implausible."""
    if data.recordings is None:
        raise ValueError("these data carry no recordings to replay")
    if classifier.manifest.mode != data.mode:
        raise ValueError(f"model is for {classifier.manifest.mode} transports, data is {data.mode}")
    sequences = np.sort(np.arange(len(data.names)) if sequences is None else sequences)
    detector = Detector(classifier)
    scores, decisions, dropped, refused = [], [], 0, 0
    for s in sequences:
        replayed = replay(data.recordings[int(s)], detector)
        if len(replayed.timestamps) != int(np.sum(data.group == s)):
            raise ValueError(f"{data.names[int(s)]}: recording and frames differ in length")
        scores.append(replayed.scores)
        decisions.append(replayed.decisions)
        dropped += replayed.dropped_frames
        refused += replayed.refused_implausible_frames
    stream = StreamScores(data, sequences, np.concatenate(scores), np.concatenate(decisions))
    return stream, dropped, refused


def robot_path_cross_validation(trainer: Trainer, cv: CrossValidation, data: FrameData) -> dict:
    """The held-out figures of a cross-validation through the robot's path: every fold's model
    exported to ONNX with its own threshold and delay, its test sequences replayed."""
    folds, dropped, refused = [], 0, 0
    with tempfile.TemporaryDirectory(prefix="vigil-robot-path-") as workdir:
        for k, (selected, held_out) in enumerate(zip(cv.folds, cv.test_scores, strict=True)):
            model_dir = Path(workdir) / f"fold-{k}"
            publish(trainer, selected, data, model_dir, version=f"{trainer.name}-fold{k}")
            stream, fold_dropped, fold_refused = replay_stream(
                FrameClassifier.from_dir(model_dir), data, held_out.sequences
            )
            folds.append((stream, selected.threshold, selected.delay_s))
            dropped += fold_dropped
            refused += fold_refused
    result = evaluate_folds(folds)
    return {
        **{key: result[key] for key in CURVE_KEYS},
        "tracker_dropped_frames": dropped,
        "tracker_refused_implausible_frames": refused,
        "recall_by_onset": result["recall_by_onset"],
        "events": result["events"],
    }
