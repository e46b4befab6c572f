"""Replay a recording through the robot's frame path (vigil.detector) and keep what it decided.

`make bench-detection` and the worker's gold-set evaluation score models this way: the
figures they report come from the tracker, depth, floor measures, streaming features, ONNX
Runtime and the delay filter a robot runs, not from features computed in bulk.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from vigil.classes import Decision
from vigil.detector import Detector
from vigil.observation import Observation


@dataclass(frozen=True)
class ReplayedRecording:
    """Per frame of one recording: time, scores and decisions of the model that decided."""

    timestamps: np.ndarray  # (n,) seconds
    scores: np.ndarray  # (n, k) in the model's class order
    raw: np.ndarray  # (n,) class index before the delay filter
    decisions: np.ndarray  # (n,) class index after the delay filter (what the robot sends)
    seen: np.ndarray  # (n,) the tracker passed on a patient
    people: np.ndarray  # (n,) people in view
    degraded: np.ndarray  # (n,) the detector was degraded (deciding with its fallback)
    refused: np.ndarray  # (n,) people in view the tracker refused as implausible

    @property
    def dropped_frames(self) -> int:
        """Frames with a plausible person in view but no patient passed on."""
        return int(np.sum((self.people - self.refused > 0) & ~self.seen))

    @property
    def refused_implausible_frames(self) -> int:
        """Frames without the patient where the tracker refused someone in view as implausible
        (vigil.tracking: furniture the pose estimator took for a person), apart from
        dropped_frames."""
        return int(np.sum((self.refused > 0) & ~self.seen))


def replay(observations: Iterable[Observation], detector: Detector) -> ReplayedRecording:
    """One recording as one stream: the detector is reset first."""
    detector.reset()
    classes = None
    times, scores, raw, decisions, seen, people, degraded, refused = ([] for _ in range(8))
    for observation in observations:
        result = detector.process(observation)
        classification = result.classification
        if classification is None:
            raise ValueError("replay needs a detector with a model")
        if classes is None:
            classes = list(classification.scores)
        times.append(observation.timestamp)
        scores.append([classification.scores[c] for c in classes])
        raw.append(classes.index(classification.raw_decision or Decision.NORMAL))
        decisions.append(classes.index(classification.decision))
        seen.append(result.seen)
        people.append(result.people)
        degraded.append(detector.degraded_)
        refused.append(result.refused)
    k = len(classes) if classes is not None else 0
    return ReplayedRecording(
        timestamps=np.asarray(times, np.float64),
        scores=np.asarray(scores, np.float64).reshape(len(times), k),
        raw=np.asarray(raw, np.int64),
        decisions=np.asarray(decisions, np.int64),
        seen=np.asarray(seen, bool),
        people=np.asarray(people, np.int64),
        degraded=np.asarray(degraded, bool),
        refused=np.asarray(refused, np.int64),
    )
