"""Writing a video with its skeleton frames (bulk insert) and finding videos by name."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from sqlalchemy import insert, select
from sqlalchemy.orm import Session

from backend.labelling.errors import Conflict, LabellingError
from backend.models.videos import Frame, Video
from vigil.skeleton import encode_depth, encode_floor, encode_keypoints

MAX_FRAMES = 10_000_000  # about 3.8 days at 30 frames/s: far more than any recording


def video_by_name(session: Session, name: str) -> Video | None:
    return session.scalars(select(Video).where(Video.name == name)).first()


def add_video(
    session: Session,
    video: Video,
    keypoints: np.ndarray,
    timestamps: Sequence[float],
    depth: np.ndarray | None = None,
    indices: Sequence[int] | None = None,
    floor: np.ndarray | None = None,
) -> Video:
    """keypoints (n, 25, 3); depth (n, 25) metres with NaN for unknown, or None; floor (n, 3)
    floor measures with NaN for unknown, or None."""
    if video_by_name(session, video.name) is not None:
        raise Conflict(f"name: a video called {video.name!r} already exists")
    indices = list(range(len(keypoints))) if indices is None else [int(i) for i in indices]
    if indices and not 0 <= min(indices) <= max(indices) < MAX_FRAMES:
        raise LabellingError(f"frames: frame numbers must lie in 0..{MAX_FRAMES - 1}")
    stamps = np.asarray(timestamps, dtype=np.float64)
    if not np.isfinite(stamps).all():
        raise LabellingError("frames: every timestamp must be a finite number")
    video.frame_count = (max(indices) + 1) if indices else 0
    if stamps.size:
        video.cover(float(stamps.min()), float(stamps.max()))
    session.add(video)
    session.flush()
    rows = []
    for i, (index, ts) in enumerate(zip(indices, timestamps, strict=True)):
        frame_depth = None
        if depth is not None and not np.all(np.isnan(depth[i])):
            frame_depth = encode_depth(depth[i])
        rows.append(
            {
                "video_id": video.id,
                "index": int(index),
                "ts": float(ts),
                "keypoints": encode_keypoints(keypoints[i]),
                "depth": frame_depth,
                "floor": None if floor is None else encode_floor(floor[i]),
            }
        )
    if rows:
        session.execute(insert(Frame), rows)
    return video
