"""Replay a recorded file: a URFD sequence (keypoint csv) or Vigil's own JSON export."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from robot_agent.sources import Observation
from vigil.classes import Decision
from vigil.datasets import urfd
from vigil.skeleton import SkeletonFrame


def replay_urfd(sequence: str, directory: Path | str | None = None) -> Iterator[Observation]:
    """Frames of one URFD sequence (e.g. ``fall-01``); truth from the official labels."""
    loaded = urfd.load(directory, names=[sequence])
    if not loaded:
        raise ValueError(f"source: URFD sequence {sequence!r} not found")
    seq = loaded[0]
    for i, frame in enumerate(seq.frames()):
        target = seq.target[i]
        truth = None
        if target == urfd.EMERGENCY:
            truth = Decision.EMERGENCY
        elif target == urfd.NORMAL:
            truth = Decision.NORMAL
        people = [frame] if seq.detected[i] else []
        yield Observation(frame.timestamp, people, truth=truth, new_transport=i == 0)


def replay_vigil_export(path: Path | str) -> Iterator[Observation]:
    """Frames of a video exported by Vigil as JSON (``GET /api/videos/{id}/export?format=json``)."""
    document = json.loads(Path(path).read_text())
    frames = document.get("frames")
    if not isinstance(frames, list):
        raise ValueError(f"source: {path} is not a Vigil JSON export (no 'frames' list)")
    for i, item in enumerate(frames):
        depth = item.get("depth")
        depth = np.array([np.nan if v is None else v for v in depth], np.float32) if depth else None
        frame = SkeletonFrame(
            np.asarray(item["keypoints"], np.float32),
            depth if depth is not None else np.full(25, np.nan, np.float32),
            timestamp=float(item.get("ts", i / 30.0)),
        )
        present = frame.keypoints[:, 2] > 0
        yield Observation(frame.timestamp, [frame] if present.any() else [], new_transport=i == 0)
