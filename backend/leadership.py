"""Which replica runs the duties that must run on exactly one replica at a time.

Several backend replicas may serve one database (docker-compose.yml; a load balancer in front).
Every replica serves robots, boards and the API, but two duties must run once: the alarm
monitor (escalations, missed Emergencies, technical alarms) and the alarm distribution's sender
and listener. Two monitors would raise each "robot offline" twice; two senders would send each
ORU^R40 twice. The replica holding the duties lock runs them; the others try again every
`retry_s` and take over when the holder is gone:

- PostgreSQL: a session-level advisory lock (`pg_try_advisory_lock`) on a connection of its
  own. It is the database that lets go: a replica killed with -9 drops its connection, the
  server ends that session and the lock with it, and the next try of another replica gets it.
  TCP keepalives on both ends bound how long a holder cut off by the network keeps it.
- SQLite: an exclusive `flock` on a file beside the database, released by the kernel when the
  process dies (replicas on one host only, as SQLite itself).
- An in-memory database: the process is alone and always holds the duties.

The holder checks its lock connection on every retry; if the connection is lost, it stops the
duties at once, since another replica may already hold the lock.
"""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import logging
import os
import time
from collections.abc import Awaitable, Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

from sqlalchemy import create_engine, text
from sqlalchemy.engine import Connection, make_url
from sqlalchemy.pool import NullPool
from starlette.concurrency import run_in_threadpool

log = logging.getLogger(__name__)

#: pg advisory lock keys (64-bit numbers no other lock of the database uses), by what they guard
LOCK_KEYS = {
    "duties": 0x5647_494C_0001,  # the backend's alarm monitor and alarm distribution
    "retention": 0x5647_494C_0002,  # a retention run (workers)
}


class DatabaseLock(Protocol):
    def try_acquire(self) -> bool: ...
    def still_held(self) -> bool: ...
    def release(self) -> None: ...


class PostgresLock:
    def __init__(self, database_url: str, key: int = LOCK_KEYS["duties"]) -> None:
        self.key = key
        # Its own engine without a pool: the connection holding the lock is never handed out.
        self._engine = create_engine(
            database_url,
            poolclass=NullPool,
            # No transaction to end: a session lock outlives statements, and the lock
            # connection never holds a snapshot open.
            isolation_level="AUTOCOMMIT",
            connect_args={
                "connect_timeout": 5,
                "keepalives": 1,
                "keepalives_idle": 5,
                "keepalives_interval": 2,
                "keepalives_count": 3,
            },
        )
        self._connection: Connection | None = None

    def try_acquire(self) -> bool:
        connection = self._engine.connect()
        try:
            # The server notices a holder cut off by the network within ~11 s, not hours.
            connection.execute(text("SET tcp_keepalives_idle = 5"))
            connection.execute(text("SET tcp_keepalives_interval = 2"))
            connection.execute(text("SET tcp_keepalives_count = 3"))
            got = connection.scalar(text("SELECT pg_try_advisory_lock(:key)"), {"key": self.key})
        except Exception:
            connection.close()
            raise
        if not got:
            connection.close()
            return False
        self._connection = connection
        return True

    def still_held(self) -> bool:
        if self._connection is None:
            return False
        try:
            self._connection.scalar(text("SELECT 1"))
            return True
        except Exception as error:
            log.error("duties lock connection lost: %s", error)
            self._drop()
            return False

    def release(self) -> None:
        if self._connection is None:
            return
        with contextlib.suppress(Exception):
            self._connection.scalar(text("SELECT pg_advisory_unlock(:key)"), {"key": self.key})
        self._drop()

    def _drop(self) -> None:
        if self._connection is not None:
            with contextlib.suppress(Exception):
                self._connection.close()
        self._connection = None
        self._engine.dispose()


class FileLock:
    """SQLite: an exclusive flock on `<database>.duties` (one host)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None

    def try_acquire(self) -> bool:
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return False
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return True

    def still_held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
        self._fd = None


class AloneLock:
    """An in-memory database: no other process can share it."""

    def __init__(self) -> None:
        self._held = False

    def try_acquire(self) -> bool:
        self._held = True
        return True

    def still_held(self) -> bool:
        return self._held

    def release(self) -> None:
        self._held = False


def lock_for(database_url: str, purpose: str = "duties") -> DatabaseLock:
    """The lock of `purpose` (a key of LOCK_KEYS) for every process on this database."""
    key = LOCK_KEYS[purpose]
    url = make_url(database_url)
    if url.get_backend_name() == "postgresql":
        return PostgresLock(database_url, key)
    if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        return FileLock(Path(f"{url.database}.{purpose}"))
    return AloneLock()


Duty = Callable[[], Awaitable[None]]


class Leadership:
    """Holds the duties lock when it can and runs `on_lead` when it gets it, `on_follow` when
    it loses it (or stops). `start()` makes the first try before it returns, so a replica
    alone starts with its duties running."""

    def __init__(
        self,
        lock: DatabaseLock,
        on_lead: Duty,
        on_follow: Duty,
        *,
        retry_s: float = 1.0,
        replica: str = "",
    ) -> None:
        self.lock = lock
        self.on_lead = on_lead
        self.on_follow = on_follow
        self.retry_s = retry_s
        self.replica = replica or f"pid {os.getpid()}"
        self.leading = False
        self.since: datetime | None = None
        self.last_error: str | None = None
        self.terms = 0  # how often this replica took the duties
        self._task: asyncio.Task | None = None

    async def start(self) -> None:
        await self._step()
        self._task = asyncio.create_task(self._run(), name="duties-leadership")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        if self.leading:
            await self._follow("stopping")
        await run_in_threadpool(self.lock.release)

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(self.retry_s)
            try:
                await self._step()
            except asyncio.CancelledError:
                raise
            except Exception:
                log.exception("duties leadership: step failed")

    async def _step(self) -> None:
        if self.leading:
            if not await run_in_threadpool(self.lock.still_held):
                await self._follow("its lock connection was lost")
            return
        try:
            got = await run_in_threadpool(self.lock.try_acquire)
        except Exception as error:  # the database is away: keep trying, say why
            self.last_error = f"{type(error).__name__}: {str(error).splitlines()[0][:200]}"
            return
        self.last_error = None
        if got:
            started = time.monotonic()
            self.leading, self.since = True, datetime.now(UTC)
            self.terms += 1
            await self.on_lead()
            log.warning(
                "replica %s runs the alarm monitor and alarm distribution (started in %.0f ms)",
                self.replica,
                (time.monotonic() - started) * 1000,
            )

    async def _follow(self, why: str) -> None:
        self.leading, self.since = False, datetime.now(UTC)
        log.warning(
            "replica %s stops the alarm monitor and alarm distribution: %s", self.replica, why
        )
        await self.on_follow()

    def status(self) -> dict:
        return {
            "replica": self.replica,
            "leading": self.leading,
            "since": self.since.isoformat() if self.since else None,
            "terms": self.terms,
            "last_error": self.last_error,
        }
