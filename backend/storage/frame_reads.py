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

from sqlalchemy import ColumnElement
from sqlalchemy.orm import Session

from backend.models.videos import Frame, Video


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
