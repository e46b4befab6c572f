"""The duties (alarm monitor, alarm distribution) run on one replica at a time: the lock on the
test database (a PostgreSQL advisory lock, or a file lock beside the SQLite file) is held by one
holder, and when that process is killed with -9 the next try of another takes it."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import textwrap
import time

import pytest

from backend.leadership import Leadership, lock_for
from tests.support.live_backend import REPO_ROOT


def _holder(database_url: str) -> subprocess.Popen:
    """Another process (a replica) that takes the duties lock and keeps it until it dies."""
    code = textwrap.dedent(
        f"""
        import sys, time
        from backend.leadership import lock_for
        lock = lock_for({database_url!r})
        print("held" if lock.try_acquire() else "refused", flush=True)
        time.sleep(120)
        """
    )
    process = subprocess.Popen(
        [sys.executable, "-c", code], cwd=REPO_ROOT, stdout=subprocess.PIPE, text=True
    )
    assert process.stdout.readline().strip() == "held"
    return process


def test_a_second_replica_gets_the_lock_only_once_the_holder_is_killed(database_url):
    holder = _holder(database_url)
    lock = lock_for(database_url)
    try:
        assert not lock.try_acquire()  # the other replica runs the duties
        holder.kill()  # SIGKILL: nothing released by the holder itself
        holder.wait()
        deadline = time.monotonic() + 5
        while not lock.try_acquire():
            assert time.monotonic() < deadline, "the lock was not freed by the holder's death"
            time.sleep(0.05)
        assert lock.still_held()
        assert not lock_for(database_url).try_acquire()  # and now nobody else gets it
    finally:
        holder.kill()
        lock.release()


def test_leadership_runs_the_duties_on_one_replica_at_a_time_and_hands_them_over(database_url):
    running: list[str] = []
    most_at_once = 0

    def duties(name: str):
        async def lead() -> None:
            nonlocal most_at_once
            running.append(name)
            most_at_once = max(most_at_once, len(running))

        async def follow() -> None:
            running.remove(name)

        return lead, follow

    async def scenario() -> None:
        first = Leadership(lock_for(database_url), *duties("first"), retry_s=0.05)
        second = Leadership(lock_for(database_url), *duties("second"), retry_s=0.05)
        await first.start()
        await second.start()
        await asyncio.sleep(0.3)
        assert (first.leading, second.leading) == (True, False)
        assert running == ["first"]
        await first.stop()  # a replica shut down: the other takes the duties on its next try
        deadline = time.monotonic() + 5
        while not second.leading:
            assert time.monotonic() < deadline, "the second replica never took over"
            await asyncio.sleep(0.02)
        assert running == ["second"]
        assert second.status()["leading"] and second.status()["terms"] == 1
        await second.stop()
        assert running == []

    asyncio.run(scenario())
    assert most_at_once == 1


def test_a_holder_that_loses_its_lock_connection_stops_its_duties(database_url):
    if not database_url.startswith("postgresql"):
        pytest.skip("a lock connection exists on PostgreSQL only (SQLite: a file lock)")
    from sqlalchemy import create_engine, text

    stopped = asyncio.Event()

    async def lead() -> None:
        pass

    async def follow() -> None:
        stopped.set()

    async def scenario() -> None:
        leadership = Leadership(lock_for(database_url), lead, follow, retry_s=0.05)
        await leadership.start()
        assert leadership.leading
        # The database ends the holder's session (a restart, a network cut).
        admin = create_engine(database_url)
        with admin.begin() as connection:
            ended = connection.scalar(
                text(
                    "SELECT count(pg_terminate_backend(pid)) FROM pg_locks "
                    "WHERE locktype = 'advisory' AND granted AND pid != pg_backend_pid()"
                )
            )
        admin.dispose()
        assert ended == 1
        await asyncio.wait_for(stopped.wait(), 5)
        assert not leadership.leading
        # Its next tries take the lock again (nobody else holds it).
        deadline = time.monotonic() + 5
        while not leadership.leading:
            assert time.monotonic() < deadline
            await asyncio.sleep(0.02)
        await leadership.stop()

    asyncio.run(scenario())
