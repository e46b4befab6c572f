"""Frame storage at hospital scale (issue 20): retention_runs, frame_archives, the index
(robot_id, ts) for alarm replay without a video and retention; PostgreSQL: frames partitioned by
UTC day of ts (id BIGINT), partitions created for every day that has robot frames and a week
ahead, a default partition for the rest; SQLite: incremental auto-vacuum (branch: storage).

Revision ID: 0011_frame_storage
Revises: 0009_urfd_dedup
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from backend.storage import partitions

revision: str = "0011_frame_storage"
down_revision: str | None = "0009_urfd_dedup"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

AHEAD_DAYS = 7


def _partition_frames(connection) -> None:
    for old, new in (
        ("frames_pkey", "frames_old_pkey"),
        ("uq_frames_robot_seq", "frames_old_robot_seq"),
        ("uq_frames_video_index", "frames_old_video_index"),
        ("ix_frames_video_ts", "frames_old_video_ts"),
    ):
        op.execute(f"ALTER INDEX {old} RENAME TO {new}")
    op.execute("ALTER TABLE frames RENAME TO frames_old")
    op.execute("ALTER SEQUENCE frames_id_seq OWNED BY NONE")
    op.execute("ALTER SEQUENCE frames_id_seq AS BIGINT")
    partitions.create_partitioned_table(connection)
    days = connection.execute(
        sa.text(
            "SELECT DISTINCT floor(ts / 86400)::bigint FROM frames_old "
            "WHERE robot_id IS NOT NULL AND ts >= :low AND ts < :high"
        ),
        {"low": partitions.PLAUSIBLE_FROM_DAY * 86400.0, "high": 4102444800.0},  # to 2100
    ).scalars()
    first = partitions.today()
    wanted = set(days) | set(range(first - 1, first + AHEAD_DAYS + 1))
    partitions.ensure_partitions(connection, sorted(wanted))
    cols = partitions.COLUMNS
    op.execute(f"INSERT INTO frames ({cols}) SELECT {cols} FROM frames_old")
    op.execute("DROP TABLE frames_old")
    op.execute("ALTER SEQUENCE frames_id_seq OWNED BY frames.id")


def _unpartition_frames(connection) -> None:
    op.execute("ALTER TABLE frames RENAME TO frames_part")
    for name in (
        "frames_pkey",
        "uq_frames_robot_seq",
        "uq_frames_video_index",
        "ix_frames_video_ts",
        "ix_frames_robot_ts",
    ):
        op.execute(f"ALTER INDEX {name} RENAME TO part_{name}")
    op.execute("ALTER SEQUENCE frames_id_seq OWNED BY NONE")
    op.execute(
        f"CREATE TABLE frames ({partitions.FRAME_COLUMNS_DDL.replace('BIGINT', 'INTEGER')}, "
        "CONSTRAINT frames_pkey PRIMARY KEY (id), "
        "CONSTRAINT uq_frames_robot_seq UNIQUE (robot_id, seq), "
        'CONSTRAINT uq_frames_video_index UNIQUE (video_id, "index"))'
    )
    op.execute("CREATE INDEX ix_frames_video_ts ON frames (video_id, ts)")
    cols = partitions.COLUMNS
    op.execute(f"INSERT INTO frames ({cols}) SELECT {cols} FROM frames_part")
    op.execute("DROP TABLE frames_part CASCADE")
    op.execute("ALTER SEQUENCE frames_id_seq AS INTEGER")
    op.execute("ALTER SEQUENCE frames_id_seq OWNED BY frames.id")


def upgrade() -> None:
    op.create_table(
        "retention_runs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("dry_run", sa.Boolean(), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("job_id", sa.Integer(), nullable=True),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("cutoff_ts", sa.Double(), nullable=False),
        sa.Column("policy", sa.JSON(), nullable=False),
        sa.Column("dropped_frames", sa.BigInteger(), nullable=False),
        sa.Column("dropped_bytes", sa.BigInteger(), nullable=False),
        sa.Column("kept", sa.JSON(), nullable=False),
        sa.Column("by_day", sa.JSON(), nullable=False),
        sa.Column("partitions_dropped", sa.JSON(), nullable=False),
        sa.Column("message", sa.Text(), nullable=False),
        sa.ForeignKeyConstraint(["job_id"], ["jobs.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_table(
        "frame_archives",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("video_id", sa.Integer(), nullable=True),
        sa.Column("video_name", sa.String(length=128), nullable=False),
        sa.Column("robot_id", sa.String(length=64), nullable=True),
        sa.Column("transport_id", sa.String(length=64), nullable=True),
        sa.Column("path", sa.String(length=1024), nullable=False),
        sa.Column("manifest_path", sa.String(length=1024), nullable=False),
        sa.Column("sha256", sa.String(length=64), nullable=False),
        sa.Column("frame_count", sa.Integer(), nullable=False),
        sa.Column("labelled_frames", sa.Integer(), nullable=False),
        sa.Column("bytes", sa.BigInteger(), nullable=False),
        sa.Column("first_ts", sa.Double(), nullable=True),
        sa.Column("last_ts", sa.Double(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("created_by_id", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(["video_id"], ["videos.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["created_by_id"], ["users.id"]),
        sa.PrimaryKeyConstraint("id"),
    )
    op.create_index("ix_frame_archives_video_name", "frame_archives", ["video_name"])
    connection = op.get_bind()
    if connection.dialect.name == "postgresql":
        _partition_frames(connection)
    else:
        op.create_index("ix_frames_robot_ts", "frames", ["robot_id", "ts"])
        if connection.dialect.name == "sqlite":
            # Retention frees pages chunk by chunk (PRAGMA incremental_vacuum); the mode
            # takes effect on an existing file only after one VACUUM.
            with op.get_context().autocommit_block():
                op.execute("PRAGMA auto_vacuum = INCREMENTAL")
                op.execute("VACUUM")


def downgrade() -> None:
    connection = op.get_bind()
    if connection.dialect.name == "postgresql":
        _unpartition_frames(connection)
    else:
        op.drop_index("ix_frames_robot_ts", table_name="frames")
    op.drop_index("ix_frame_archives_video_name", table_name="frame_archives")
    op.drop_table("frame_archives")
    op.drop_table("retention_runs")
