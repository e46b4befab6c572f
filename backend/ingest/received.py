"""A validated frame batch as compact rows, the form the writer queues until the commit.

A pydantic FrameRecord holds some 30 Python containers (the nested keypoint lists). Thousands
of them waiting for a commit made the cyclic garbage collector the largest cost of ingest; a
ReceivedFrame is one tuple of scalars, blobs and text that the collector soon stops tracking.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import chain
from typing import NamedTuple

from vigil.classes import Decision
from vigil.protocol import FrameBatch, FrameRecord
from vigil.skeleton import N_FLOOR, N_KEYPOINTS

_KEYPOINTS = struct.Struct(f"<{N_KEYPOINTS * 3}f")
_DEPTH = struct.Struct(f"<{N_KEYPOINTS}f")
_FLOOR = struct.Struct(f"<{N_FLOOR}f")
_NAN = float("nan")


class ReceivedFrame(NamedTuple):
    """One frame; the fields from `keypoints` on are the tail of a row of bulk.FRAME_COLUMNS."""

    seq: int
    ts: float
    transport_id: str | None
    keypoints: bytes
    depth: bytes | None
    floor: bytes | None
    decision: str | None
    scores: str | None
    model_version: str | None
    threshold: float | None
    delay_ms: int | None
    shadow_decision: str | None
    shadow_scores: str | None
    shadow_model_version: str | None


ROW_TAIL_START = ReceivedFrame._fields.index("keypoints")


@dataclass(slots=True)
class ReceivedFrames:
    """A robot's frame batch, validated and compacted."""

    frames: list[ReceivedFrame]


def shows_person(keypoints: bytes) -> bool:
    """Whether packed keypoints hold any keypoint (confidence above 0): the robot saw its
    patient in this frame (a frame without the patient travels with every keypoint missing)."""
    return any(c > 0 for c in _KEYPOINTS.unpack(keypoints)[2::3])


def pack_keypoints(keypoints: list[list[float]]) -> bytes:
    """Same bytes as vigil.skeleton.encode_keypoints (25 x 3 little-endian float32), without
    building a numpy array per frame."""
    return _KEYPOINTS.pack(*chain.from_iterable(keypoints))


def pack_depth(depth: list[float | None] | None) -> bytes | None:
    """Same bytes as vigil.skeleton.encode_depth; null (unknown) becomes NaN."""
    if depth is None:
        return None
    return _DEPTH.pack(*(_NAN if v is None else v for v in depth))


def pack_floor(floor: list[float | None] | None) -> bytes | None:
    """Same bytes as vigil.skeleton.encode_floor; null (unknown) becomes NaN."""
    if floor is None or all(v is None for v in floor):
        return None
    return _FLOOR.pack(*(_NAN if v is None else v for v in floor))


def scores_json(scores: dict[Decision, float]) -> str | None:
    """The text json.dumps gives for validated scores (plain keys, finite floats), faster."""
    if not scores:
        return None
    return "{" + ", ".join(f'"{k.value}": {v!r}' for k, v in scores.items()) + "}"


def compact(frame: FrameRecord) -> ReceivedFrame:
    decision = frame.decision
    shadow = frame.shadow
    return ReceivedFrame(
        frame.seq,
        frame.ts,
        frame.transport_id,
        pack_keypoints(frame.keypoints),
        pack_depth(frame.depth),
        pack_floor(frame.floor),
        decision.value if decision else None,
        scores_json(frame.scores),
        frame.model_version,
        frame.threshold,
        frame.delay_ms,
        shadow.decision.value if shadow else None,
        scores_json(shadow.scores) if shadow else None,
        shadow.model_version if shadow else None,
    )


def compact_all(frames: Iterable[FrameRecord]) -> list[ReceivedFrame]:
    return [compact(frame) for frame in frames]


def from_batch(batch: FrameBatch) -> ReceivedFrames:
    return ReceivedFrames(compact_all(batch.frames))
