"""Per-frame labels <-> runs of equal labels (segments), and the one rule for overlaps.

Where segments overlap, the one updated last wins the frame (on a tie, the one created later):
`frame_segments` applies it for the exports, the Parquet archives and training alike. Plain
functions over anything with a segment's fields, so every process (the backend's labelling and
storage, the worker) takes the one rule from here.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from datetime import datetime
from typing import Protocol, TypeVar


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


S = TypeVar("S", bound="_Segment")


class _Segment(Protocol):
    id: int
    first_frame: int
    last_frame: int
    label_key: str
    updated_at: datetime


def overlap_order(segment: _Segment) -> tuple[datetime, int]:
    """The declared rule for overlapping segments: sorted by this key, a later segment wins the
    frames it shares with an earlier one, i.e. the segment updated last wins (on a tie, the one
    created later: the higher id)."""
    return (segment.updated_at, segment.id)


def frame_segments(frame_count: int, segments: Iterable[S]) -> list[S | None]:
    """Per frame, the segment that labels it (None: no segment covers it), by `overlap_order`.

    The one road from segments to per-frame labels: the exports (CSV, COCO) and the training
    rows (worker.db_data) both take their labels from here, so they agree row by row."""
    winner: list[S | None] = [None] * frame_count
    for segment in sorted(segments, key=overlap_order):
        for i in range(max(segment.first_frame, 0), min(segment.last_frame, frame_count - 1) + 1):
            winner[i] = segment
    return winner


def segment_labels(frame_count: int, segments: Iterable[_Segment]) -> list[str | None]:
    """Per frame, the label key of the segment that wins it (`frame_segments`)."""
    return [None if s is None else s.label_key for s in frame_segments(frame_count, segments)]
