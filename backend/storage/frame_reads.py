"""Reads of one video's frames that PostgreSQL can prune to the day partitions holding it.

`frames` is partitioned by day of ts (backend/storage/partitions.py); a predicate on video_id
alone makes the planner probe the indexes of every partition (40 and more with a month of
history: planning and one index descent per partition, cold after a while). Every video keeps
the smallest and largest ts of its frames (Video.first_frame_ts / last_frame_ts, widened by
every writer in the same transaction as the frames), so a read by video adds `ts BETWEEN` them
and touches only its days. SQLite has no partitions: there the predicate is left out so the
planner keeps the (video_id, index) index it picks today.
"""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import ColumnElement, Row
from sqlalchemy.orm import Session

from backend.models.videos import Frame, Video
from vigil.skeleton import N_FLOOR, N_KEYPOINTS, decode_many


def prunes(session: Session) -> bool:
    """Whether the database partitions frames by ts (PostgreSQL)."""
    return session.get_bind().dialect.name == "postgresql"


def of_video(session: Session, video: Video) -> list[ColumnElement[bool]]:
    """WHERE clauses for the frames of `video`: its id, and on PostgreSQL its ts range when
    known (a video without one, or with frames written before migration 0012 filled it, is read
    from every partition: slower, never incomplete)."""
    clauses = [Frame.video_id == video.id]
    first, last = video.first_frame_ts, video.last_frame_ts
    if first is not None and last is not None and prunes(session):
        clauses.append(Frame.ts.between(first, last))
    return clauses


def json_frames(rows: Sequence[Row]) -> list[dict]:
    """Frame rows (any columns; keypoints, depth and floor as stored blobs) as the API's JSON
    values, decoded once for all rows: keypoints (25, 3) lists, depth and floor lists with None
    for unknown (JSON has no NaN), None where the blob is None. The same values as
    vigil.skeleton's decode_keypoints(...).tolist(), depth_to_json and floor_to_json per frame,
    without a pydantic model per frame (a replay has 600 and more)."""
    if not rows:
        return []
    names = rows[0]._fields
    out = [dict(zip(names, row, strict=True)) for row in rows]
    if "keypoints" in names:
        blobs = [frame["keypoints"] for frame in out]
        points = decode_many(blobs, N_KEYPOINTS * 3).reshape(len(out), N_KEYPOINTS, 3).tolist()
        for frame, value in zip(out, points, strict=True):
            frame["keypoints"] = value
    for name, width in (("depth", N_KEYPOINTS), ("floor", N_FLOOR)):
        if name in names:
            blobs = [frame[name] for frame in out]
            values = decode_many(blobs, width).tolist()
            for frame, blob, value in zip(out, blobs, values, strict=True):
                frame[name] = None if blob is None else [None if v != v else v for v in value]
    return out
