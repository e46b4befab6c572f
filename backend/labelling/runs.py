"""Per-frame labels <-> runs of equal labels (segments)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def label_runs(labels: Sequence[str | None]) -> list[tuple[int, int, str]]:
    """[(first, last, label)] for maximal runs of equal labels; None frames are gaps."""
    runs: list[tuple[int, int, str]] = []
    start = None
    for i, label in enumerate([*labels, None]):
        if start is not None and label != labels[start]:
            runs.append((start, i - 1, labels[start]))
            start = None
        if start is None and label is not None:
            start = i
    return runs


def frame_labels(frame_count: int, segments: Iterable[tuple[int, int, str]]) -> list[str | None]:
    """One label per frame; where segments overlap the later one in the iterable wins."""
    labels: list[str | None] = [None] * frame_count
    for first, last, label in segments:
        for i in range(max(first, 0), min(last, frame_count - 1) + 1):
            labels[i] = label
    return labels
