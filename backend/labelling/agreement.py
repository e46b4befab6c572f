"""Agreement between two annotators of one video.

Per label: Cohen's kappa of "this frame has the label" between the two, over the frames both
labelled. Per fall stage (labels that are Emergency in the video's mode): onset and offset
difference in milliseconds (B minus A) of the first run of that label.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vigil.segments import frame_labels, label_runs


def cohen_kappa(a: np.ndarray, b: np.ndarray) -> float | None:
    """Kappa of two equally long label arrays; None when undefined (chance agreement is 1)."""
    if len(a) == 0:
        return None
    categories = np.union1d(a, b)
    observed = float(np.mean(a == b))
    expected = float(sum(np.mean(a == c) * np.mean(b == c) for c in categories))
    if expected >= 1.0:
        return None
    return (observed - expected) / (1.0 - expected)


@dataclass(frozen=True, slots=True)
class LabelAgreement:
    label_key: str
    kappa: float | None
    frames_a: int
    frames_b: int


@dataclass(frozen=True, slots=True)
class StageTiming:
    label_key: str
    onset_a_ms: float | None
    onset_b_ms: float | None
    onset_diff_ms: float | None
    offset_a_ms: float | None
    offset_b_ms: float | None
    offset_diff_ms: float | None


@dataclass(frozen=True, slots=True)
class Agreement:
    frames_compared: int
    overall_kappa: float | None
    labels: list[LabelAgreement]
    stages: list[StageTiming]


def agreement(
    frame_count: int,
    fps: float,
    segments_a: list[tuple[int, int, str]],
    segments_b: list[tuple[int, int, str]],
    fall_stages: set[str],
) -> Agreement:
    labels_a = frame_labels(frame_count, segments_a)
    labels_b = frame_labels(frame_count, segments_b)
    both = [i for i in range(frame_count) if labels_a[i] is not None and labels_b[i] is not None]
    a = np.array([labels_a[i] for i in both], dtype=object)
    b = np.array([labels_b[i] for i in both], dtype=object)
    keys = sorted({*a.tolist(), *b.tolist()})
    per_label = [
        LabelAgreement(
            key, cohen_kappa(a == key, b == key), int((a == key).sum()), int((b == key).sum())
        )
        for key in keys
    ]
    first_runs_a = _first_runs(labels_a)
    first_runs_b = _first_runs(labels_b)
    ms = 1000.0 / fps
    stages = []
    for key in sorted(fall_stages & (first_runs_a.keys() | first_runs_b.keys())):
        ra, rb = first_runs_a.get(key), first_runs_b.get(key)
        onset_a = ra[0] * ms if ra else None
        onset_b = rb[0] * ms if rb else None
        offset_a = (ra[1] + 1) * ms if ra else None
        offset_b = (rb[1] + 1) * ms if rb else None
        stages.append(
            StageTiming(
                key,
                onset_a,
                onset_b,
                onset_b - onset_a if ra and rb else None,
                offset_a,
                offset_b,
                offset_b - offset_a if ra and rb else None,
            )
        )
    return Agreement(len(both), cohen_kappa(a, b) if len(both) else None, per_label, stages)


def _first_runs(labels: list[str | None]) -> dict[str, tuple[int, int]]:
    runs: dict[str, tuple[int, int]] = {}
    for first, last, key in label_runs(labels):
        runs.setdefault(key, (first, last))
    return runs
