"""PostgreSQL: `frames` partitioned by UTC day of `ts` (declarative range partitioning).

Partition `frames_pYYYYMMDD` holds [day start, next day start): a frame at exactly midnight
belongs to the new day. `frames_default` takes every frame no day partition covers (a day not
created yet, a robot clock that stepped, imported recordings whose ts counts from 0), so no frame
is ever refused. Creating a day partition moves that day's rows out of the default partition in
the same transaction, so a partition can always be created later.

Retention never runs a DELETE on the whole table, and never detaches a partition: a day that is
entirely older than the cutoff is truncated and given back its kept frames in one transaction
that locks only that day's partition (backend/storage/retention.py says why: DETACH and ATTACH
lock the parent that every ingest insert needs). Only the default partition is deleted from, in
bounded chunks.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime

from sqlalchemy import Connection, text

from backend.storage.policy import DAY_S

DEFAULT_PARTITION = "frames_default"
# Any robot frame before 2000-01-01 is a clock fault: no day partition is created for it.
PLAUSIBLE_FROM_DAY = 10957

FRAME_COLUMNS_DDL = """
    id BIGINT NOT NULL DEFAULT nextval('frames_id_seq'),
    video_id INTEGER NOT NULL REFERENCES videos (id) ON DELETE CASCADE,
    "index" INTEGER NOT NULL,
    ts DOUBLE PRECISION NOT NULL,
    robot_id VARCHAR(64),
    seq INTEGER,
    keypoints BYTEA NOT NULL,
    depth BYTEA,
    decision VARCHAR(16),
    scores JSON,
    model_version VARCHAR(64),
    threshold DOUBLE PRECISION,
    delay_ms INTEGER,
    shadow_decision VARCHAR(16),
    shadow_scores JSON,
    shadow_model_version VARCHAR(64),
    floor BYTEA
"""
COLUMNS = (
    'id, video_id, "index", ts, robot_id, seq, keypoints, depth, decision, scores, '
    "model_version, threshold, delay_ms, shadow_decision, shadow_scores, "
    "shadow_model_version, floor"
)
# The partition key (ts) is part of every unique key; a resent frame has the same ts.
INDEXES = (
    ("frames_pkey", "PRIMARY KEY", "(id, ts)"),
    ("uq_frames_robot_seq", "UNIQUE", "(robot_id, seq, ts)"),
    ("uq_frames_video_index", "UNIQUE", '(video_id, "index", ts)'),
    ("ix_frames_video_ts", "INDEX", "(video_id, ts)"),
    ("ix_frames_robot_ts", "INDEX", "(robot_id, ts)"),
)


def partition_name(day: int) -> str:
    return "frames_p" + datetime.fromtimestamp(day * DAY_S, UTC).strftime("%Y%m%d")


def bounds(day: int) -> tuple[float, float]:
    return day * DAY_S, (day + 1) * DAY_S


def today(now: float | None = None) -> int:
    return int((time.time() if now is None else now) // DAY_S)


def create_partitioned_table(connection: Connection, name: str = "frames") -> None:
    connection.execute(text(f"CREATE TABLE {name} ({FRAME_COLUMNS_DDL}) PARTITION BY RANGE (ts)"))
    for index_name, kind, columns in INDEXES:
        if kind == "INDEX":
            connection.execute(text(f"CREATE INDEX {index_name} ON {name} {columns}"))
        else:
            connection.execute(
                text(f"ALTER TABLE {name} ADD CONSTRAINT {index_name} {kind} {columns}")
            )
    connection.execute(text(f"CREATE TABLE {DEFAULT_PARTITION} PARTITION OF {name} DEFAULT"))


def is_partitioned(connection: Connection) -> bool:
    return bool(
        connection.execute(
            text(
                "SELECT 1 FROM pg_partitioned_table p JOIN pg_class c ON c.oid = p.partrelid "
                "WHERE c.relname = 'frames' AND c.relnamespace = current_schema()::regnamespace"
            )
        ).first()
    )


def day_partitions(connection: Connection) -> dict[int, str]:
    """Day number -> partition name of every attached day partition."""
    rows = connection.execute(
        text(
            "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid "
            "JOIN pg_class p ON p.oid = i.inhparent WHERE p.relname = 'frames' "
            "AND p.relnamespace = current_schema()::regnamespace"
        )
    ).scalars()
    days = {}
    for name in rows:
        if name.startswith("frames_p") and len(name) == 16:
            day = datetime.strptime(name[8:], "%Y%m%d").replace(tzinfo=UTC)
            days[int(day.timestamp() // DAY_S)] = name
    return days


def _new_table_like_frames(connection: Connection, name: str, day: int) -> None:
    low, high = bounds(day)
    connection.execute(text(f"DROP TABLE IF EXISTS {name}"))
    connection.execute(
        text(f"CREATE TABLE {name} (LIKE frames INCLUDING DEFAULTS INCLUDING CONSTRAINTS)")
    )
    # Lets ATTACH PARTITION skip its validation scan.
    connection.execute(
        text(
            f"ALTER TABLE {name} ADD CONSTRAINT {name}_bounds "
            f"CHECK (ts >= {low!r} AND ts < {high!r})"
        )
    )


def create_day_partition(connection: Connection, day: int) -> str:
    """Create and attach the partition of `day`, moving its rows out of the default partition
    (in the caller's transaction)."""
    name = partition_name(day)
    low, high = bounds(day)
    _new_table_like_frames(connection, name, day)
    connection.execute(
        text(
            f"WITH moved AS (DELETE FROM {DEFAULT_PARTITION} WHERE ts >= :low AND ts < :high "
            f"RETURNING {COLUMNS}) INSERT INTO {name} ({COLUMNS}) SELECT {COLUMNS} FROM moved"
        ),
        {"low": low, "high": high},
    )
    connection.execute(
        text(f"ALTER TABLE frames ATTACH PARTITION {name} FOR VALUES FROM ({low!r}) TO ({high!r})")
    )
    return name


def ensure_partitions(connection: Connection, days: list[int] | range) -> list[str]:
    """Create the day partitions of `days` that are missing; returns the names created."""
    existing = day_partitions(connection)
    return [create_day_partition(connection, d) for d in sorted(set(days)) if d not in existing]


def ensure_ahead(connection: Connection, ahead_days: int, now: float | None = None) -> list[str]:
    """Yesterday (a late frame), today and `ahead_days` days ahead."""
    first = today(now)
    return ensure_partitions(connection, range(first - 1, first + ahead_days + 1))


def partition_sizes(connection: Connection) -> dict[str, int]:
    """Bytes on disk (table, TOAST and indexes) of every partition of frames."""
    rows = connection.execute(
        text(
            "SELECT c.relname, pg_total_relation_size(c.oid) FROM pg_inherits i "
            "JOIN pg_class c ON c.oid = i.inhrelid JOIN pg_class p ON p.oid = i.inhparent "
            "WHERE p.relname = 'frames' AND p.relnamespace = current_schema()::regnamespace"
        )
    ).all()
    return {name: int(size) for name, size in rows}


def include_object(obj, name, type_, reflected, compare_to) -> bool:
    """Alembic comparison filter for a PostgreSQL database: the day partitions are not tables
    of the models, and frames' unique keys there carry ts (the partition key) by design."""
    if type_ == "table" and name and (name.startswith("frames_p") or name == DEFAULT_PARTITION):
        return False
    table = getattr(obj, "table", None)
    return not (type_ in ("unique_constraint", "index") and getattr(table, "name", "") == "frames")
