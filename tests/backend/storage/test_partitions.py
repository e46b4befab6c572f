"""PostgreSQL day partitions of frames on a throwaway database: created ahead, a frame at
midnight lands in the new day, a frame no partition covers (clock step, day not created yet,
imported recording) lands in the default partition and moves when its day is created; retention
replaces a whole old day by its kept frames and drops the rest, never a table-wide DELETE."""

from __future__ import annotations

import psycopg
import pytest
from sqlalchemy import func, select, text

from backend.db import transaction
from backend.models import Frame
from backend.storage import partitions
from backend.storage.policy import DAY_S
from backend.storage.retention import run_retention
from tests.backend.storage import factories as f


def rows_in(session, table: str) -> int:
    return session.execute(text(f"SELECT count(*) FROM {table}")).scalar_one()


def test_partitions_created_ahead_midnight_default_and_retention_swap(pg_factory):
    today = partitions.today()
    old = int(f.CUTOFF_DAY // DAY_S) - 5
    with transaction(pg_factory) as session:
        connection = session.connection()
        assert partitions.is_partitioned(connection)
        days = partitions.day_partitions(connection)
        assert set(range(today - 1, today + 8)) <= set(days)  # the migration's week ahead
        partitions.ensure_partitions(connection, [old, old + 1])
        midnight = (old + 1) * DAY_S
        video = f.robot_video(
            session,
            "r1-old",
            "r1",
            [
                midnight - 0.001,
                midnight,
                midnight + 1.0,
                (old - 3) * DAY_S + 5,  # no partition for that day yet
                1.0e9,
            ],
        )  # fmt: skip  a robot clock stepped back to 2001
        f.alarm(session, "r1", midnight + 1.0, midnight + 1.0)  # keeps midnight-59 .. +31
        f.robot_video(session, "r1-now", "r1", [f.NOW - 10, f.NOW], first_seq=100)
        f.robot_video(session, "urfd/fall-01", None, [0.0, 1 / 30])
    with transaction(pg_factory) as session:
        assert rows_in(session, partitions.partition_name(old)) == 1
        assert rows_in(session, partitions.partition_name(old + 1)) == 2
        assert rows_in(session, partitions.DEFAULT_PARTITION) == 4  # 2 odd robot + 2 imported
        # Creating the missing day moves its frame out of the default partition.
        partitions.ensure_partitions(session.connection(), [old - 3])
        assert rows_in(session, partitions.partition_name(old - 3)) == 1
        assert rows_in(session, partitions.DEFAULT_PARTITION) == 3
        assert session.scalar(select(func.count()).select_from(Frame)) == 9

    # A resent frame (same robot, seq and ts) is refused by the unique key.
    with pytest.raises(psycopg.errors.UniqueViolation), transaction(pg_factory) as session:
        f.robot_video(session, "r1-dup", "r1", [f.NOW], first_seq=101)

    result = run_retention(pg_factory, f.policy_settings(), now=f.NOW)
    assert set(result["partitions_dropped"]) >= {partitions.partition_name(d)
                                                 for d in (old - 3, old, old + 1)}  # fmt: skip
    with transaction(pg_factory) as session:
        left = {(r.video_id, r.ts) for r in session.execute(select(Frame.video_id, Frame.ts))}
        days = partitions.day_partitions(session.connection())
        assert rows_in(session, partitions.partition_name(old)) == 1  # in the alarm window
        assert rows_in(session, partitions.partition_name(old - 3)) == 0
    # The swapped day partitions are attached again (with their kept frames) under their names.
    assert {old - 3, old, old + 1} <= set(days)
    assert (video.id, midnight - 0.001) in left and (video.id, midnight) in left
    assert (video.id, midnight + 1.0) in left
    assert (video.id, (old - 3) * DAY_S + 5) not in left
    assert (video.id, 1.0e9) not in left  # from the default partition, in chunks
    assert result["dropped_frames"] == 2
    assert len(left) == 9 - 2
    assert result["kept"] == {"alarm_window": 3}
