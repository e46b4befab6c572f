"""Reads by video that prune (issue 20): videos.first_frame_ts / last_frame_ts, the smallest and
largest ts of the video's frames, filled from the frames already stored. Reads by video add
`ts BETWEEN` them, so that PostgreSQL reads only the day partitions holding the video instead of
probing the indexes of every partition (`backend.storage.frame_reads`).

Revision ID: 0012_video_frame_range
Revises: 0011_frame_storage
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0012_video_frame_range"
down_revision: str | None = "0011_frame_storage"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("videos", sa.Column("first_frame_ts", sa.Double(), nullable=True))
    op.add_column("videos", sa.Column("last_frame_ts", sa.Double(), nullable=True))
    # One pass over frames (SQLite >= 3.33 and PostgreSQL both have UPDATE ... FROM).
    op.execute(
        "UPDATE videos SET first_frame_ts = r.lo, last_frame_ts = r.hi FROM "
        "(SELECT video_id, min(ts) AS lo, max(ts) AS hi FROM frames GROUP BY video_id) AS r "
        "WHERE videos.id = r.video_id"
    )


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35): a batch copy of `videos` would drop the
    # table that frames, alarms and segments reference (refused with foreign keys on).
    for column in ("last_frame_ts", "first_frame_ts"):
        op.execute(f"ALTER TABLE videos DROP COLUMN {column}")
