"""PostgreSQL day partitions of frames on a throwaway database: created ahead, a frame at
midnight lands in the new day, a frame no partition covers (clock step, day not created yet,
imported recording) lands in the default partition and moves when its day is created; retention
leaves an old day with only its kept frames (TRUNCATE, kept rows back; the partition stays
attached), never a table-wide DELETE, and locks nothing of the parent `frames` that an ingest
insert would wait for."""

from __future__ import annotations

import threading
import time

import psycopg
import pytest
from sqlalchemy import func, select, text
from sqlalchemy.exc import OperationalError

from backend.db import transaction
from backend.models import Frame
from backend.storage import partitions, queries, retention
from backend.storage.policy import DAY_S, RetentionPolicy
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
        )  # a robot clock stepped back to 2001
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
    # Only the days with a frame to drop are trimmed (old and old + 1 keep all theirs).
    assert partitions.partition_name(old - 3) in result["partitions_dropped"]
    assert not {partitions.partition_name(d) for d in (old, old + 1)} & set(
        result["partitions_dropped"]
    )
    with transaction(pg_factory) as session:
        left = {(r.video_id, r.ts) for r in session.execute(select(Frame.video_id, Frame.ts))}
        days = partitions.day_partitions(session.connection())
        assert rows_in(session, partitions.partition_name(old)) == 1  # in the alarm window
        assert rows_in(session, partitions.partition_name(old - 3)) == 0
    # The day partitions stay attached (with their kept frames) under their names.
    assert {old - 3, old, old + 1} <= set(days)
    assert (video.id, midnight - 0.001) in left and (video.id, midnight) in left
    assert (video.id, midnight + 1.0) in left
    assert (video.id, (old - 3) * DAY_S + 5) not in left
    assert (video.id, 1.0e9) not in left  # from the default partition, in chunks
    assert result["dropped_frames"] == 2
    assert len(left) == 9 - 2
    assert result["kept"] == {"alarm_window": 3}


def test_retention_trims_attached_partitions_without_blocking_an_insert(pg_factory, monkeypatch):
    """While a day partition is trimmed (after its TRUNCATE, before the commit), the parent
    `frames` carries no lock beyond what an insert takes itself, the partition is still
    attached, and a frame inserted into `frames` on another connection goes in at once. The
    retention keeps exactly the policy's frames."""
    old = int(f.CUTOFF_DAY // DAY_S) - 5
    with transaction(pg_factory) as session:
        partitions.ensure_partitions(session.connection(), [old, old + 1])
        t = old * DAY_S + 3600
        f.robot_video(session, "r1-old", "r1", [t + i for i in range(600)])
        f.alarm(session, "r1", t + 200, t + 210)  # keeps t+140 .. t+240
        day_after = [(old + 1) * DAY_S + i for i in range(50)]
        labelled = f.robot_video(session, "r2-old", "r2", day_after)
        f.label(session, labelled, 1, 3)
        live = f.robot_video(session, "r3-live", "r3", [f.NOW - 1], first_seq=0)
        live_id = live.id
        before = f.frame_rows(session)
        facts = queries.policy_facts(session, RetentionPolicy(days=30), f.NOW)
    expected = {i for i, (v, r, ts, idx) in before.items() if facts.reason(v, r, ts, idx)}
    url = pg_factory.kw["bind"].url.render_as_string(hide_password=False).replace("+psycopg", "")
    seen: dict = {}

    def hook(connection, name: str) -> None:
        pid = connection.execute(text("SELECT pg_backend_pid()")).scalar_one()
        seen["parent_locks"] = set(
            connection.execute(
                text(
                    "SELECT mode FROM pg_locks WHERE pid = :pid AND relation = 'frames'::regclass"
                ),
                {"pid": pid},
            ).scalars()
        )
        seen["partition_locks"] = set(
            connection.execute(
                text(
                    f"SELECT mode FROM pg_locks WHERE pid = :pid AND relation = '{name}'::regclass"
                ),
                {"pid": pid},
            ).scalars()
        )
        seen["attached"] = name in set(partitions.day_partitions(connection).values())
        with psycopg.connect(url, autocommit=True) as other:
            other.execute("SET lock_timeout = '2s'")
            started = time.perf_counter()
            other.execute(
                'INSERT INTO frames (video_id, "index", ts, robot_id, seq, keypoints) '
                "VALUES (%s, 1, %s, 'r3', 1, %s)",
                (live_id, f.NOW, b"\x00" * 8),
            )
            seen.setdefault("insert_s", []).append(time.perf_counter() - started)

    monkeypatch.setattr(retention, "after_truncate_hook", hook)
    result = run_retention(pg_factory, f.policy_settings(), now=f.NOW)
    assert seen, "the retention never truncated a day partition"
    assert seen["parent_locks"] <= {"AccessShareLock", "RowExclusiveLock"}, seen
    assert "AccessExclusiveLock" in seen["partition_locks"]
    assert seen["attached"]
    assert max(seen["insert_s"]) < 1.0
    with transaction(pg_factory) as session:
        after = f.frame_rows(session)
        days = partitions.day_partitions(session.connection())
    assert {old, old + 1} <= set(days)
    live_frames = {i for i, (v, *_rest) in after.items() if v == live_id}
    assert len(live_frames) == 2  # the one inserted during the retention is there
    assert set(after) - live_frames == {i for i in expected if before[i][0] != live_id}
    assert result["dropped_frames"] == 600 - 101
    assert result["kept"] == {"alarm_window": 101, "labelled": 50}
    assert result["partitions_dropped"] == [partitions.partition_name(old)]
    assert result["disk_bytes_freed"] > 0


def test_a_partition_lock_waits_in_short_tries_and_leaves_the_transaction_usable(
    pg_factory, monkeypatch
):
    """lock_partition never queues behind a holder for long: each try gives up after its
    lock_timeout inside a savepoint, so the transaction goes on, and it gets the lock once the
    holder lets go; when the holder never does, it raises after its last try."""
    day = partitions.today() + 1
    name = partitions.partition_name(day)
    url = pg_factory.kw["bind"].url.render_as_string(hide_password=False).replace("+psycopg", "")
    with psycopg.connect(url) as holder:
        holder.execute(f"LOCK TABLE {name} IN ACCESS EXCLUSIVE MODE")  # held until commit
        with pytest.raises(OperationalError), pg_factory() as session:
            monkeypatch.setattr(retention, "LOCK_TRIES", 3)
            connection = session.connection()
            try:
                retention.lock_partition(connection, name, "SHARE")
            finally:
                assert connection.execute(text("SELECT 1")).scalar_one() == 1  # still usable
        monkeypatch.setattr(retention, "LOCK_TRIES", 40)
        release = threading.Timer(0.3, holder.commit)
        release.start()
        started = time.perf_counter()
        with pg_factory() as session:
            retention.lock_partition(session.connection(), name, "SHARE")
            waited = time.perf_counter() - started
            assert session.execute(text("SELECT count(*) FROM " + name)).scalar_one() == 0
        release.join()
    assert 0.25 < waited < 5
