"""One retention run: apply the policy (backend/storage/policy.py) and record what it dropped,
how much, and what it kept and why (a `retention_runs` row). A dry run records the same
figures without dropping anything. The kept frames are chosen over whole columns with numpy
(`PolicyFacts.reasons`), not one Python step per row: a run competes with the backend for CPU.

SQLite: frames are deleted in chunks, each its own short write transaction followed by
`PRAGMA incremental_vacuum` (the pages go back to the file system) and a pause that lets ingest
commit. The chunk size adapts so that each chunk holds the write lock for about
`retention_chunk_hold_ms` (`ChunkSizer`): the lock is never held long enough to delay an
acknowledgement, whatever the machine's speed.

PostgreSQL: day partitions stay attached. Each day partition entirely older than the cutoff is
trimmed in one transaction: SHARE lock on that partition (it takes no new frames, old days get
none anyway), the kept ids chosen, the kept rows copied to a temporary table, the partition
TRUNCATEd (ACCESS EXCLUSIVE on that partition only, taken with a short lock_timeout inside a
savepoint and retried with backoff, so no reader queues behind it for long) and the kept rows
inserted back. TRUNCATE gives the disk space back at once. The parent `frames` is never locked
beyond what any insert takes: an earlier design swapped in a new partition with DETACH/ATTACH
PARTITION, which lock the parent that every ingest insert needs, and acknowledgements queued
behind it for seconds. The default partition is deleted from in chunks. Never a DELETE over the
whole table.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np
from sqlalchemy import Connection, text
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.leadership import lock_for
from backend.metrics import summary_ms
from backend.models.storage import RetentionRun, RetentionRunStatus
from backend.storage import partitions, queries
from backend.storage.policy import DAY_S, DROPPED_CODE, REASON_CODES, PolicyFacts, RetentionPolicy
from backend.unit_of_work import savepoint
from vigil.states import StateMachine

log = logging.getLogger(__name__)

Progress = Callable[[float, str], None]
#: SQLite: pages given back after a chunk at least (more when the chunk freed more).
VACUUM_PAGES_PER_CHUNK = 512
SQLITE_PAGE_BYTES = 4096
#: PostgreSQL: attempts at one day partition (a failed attempt rolls back and starts again).
TRIM_ATTEMPTS = 5
#: PostgreSQL: how long one try to take a day partition's lock may wait, the tries, and the
#: longest pause between them. A lock request waiting in the queue blocks the requests behind
#: it, so it must give up quickly rather than queue readers of that day.
LOCK_TIMEOUT_MS = 50
LOCK_TRIES = 40
LOCK_BACKOFF_MAX_S = 2.0
#: Called inside a day's transaction once the partition is truncated and its kept rows are
#: back (before the commit); the tests hold the transaction open there.
after_truncate_hook: Callable[[Connection, str], None] | None = None

RETENTION_RUN = StateMachine(
    RetentionRunStatus,
    edges={
        RetentionRunStatus.RUNNING: {RetentionRunStatus.DONE, RetentionRunStatus.FAILED},
        RetentionRunStatus.DONE: set(),
        RetentionRunStatus.FAILED: set(),
    },
    initial=RetentionRunStatus.RUNNING,
    subject="retention run",
)


@dataclass
class Tally:
    dropped: int = 0
    dropped_bytes: int = 0
    kept: Counter = field(default_factory=Counter)
    by_day: dict[str, dict[str, int]] = field(default_factory=dict)
    partitions_dropped: list[str] = field(default_factory=list)
    disk_bytes_freed: int = 0
    chunk_holds_ms: list[float] = field(default_factory=list)  # SQLite: each chunk's write hold

    def merge(self, other: Tally) -> None:
        self.dropped += other.dropped
        self.dropped_bytes += other.dropped_bytes
        self.kept.update(other.kept)
        self.disk_bytes_freed += other.disk_bytes_freed
        for day, entry in other.by_day.items():
            mine = self.by_day.setdefault(day, {"dropped": 0, "dropped_bytes": 0, "kept": 0})
            for key, value in entry.items():
                mine[key] += value

    def add_many(self, ts: np.ndarray, codes: np.ndarray, nbytes: np.ndarray) -> None:
        """Count frames (columns) by their `PolicyFacts.reasons` codes."""
        if not len(ts):
            return
        dropped = codes == DROPPED_CODE
        self.dropped += int(dropped.sum())
        self.dropped_bytes += int(nbytes[dropped].sum())
        for code, count in zip(*np.unique(codes[~dropped], return_counts=True), strict=True):
            self.kept[REASON_CODES[int(code)]] += int(count)
        days = np.floor_divide(ts, DAY_S).astype(np.int64)  # policy.day_of
        for day in np.unique(days):
            on_day = days == day
            name = datetime.fromtimestamp(int(day) * DAY_S, UTC).strftime("%Y-%m-%d")
            entry = self.by_day.setdefault(name, {"dropped": 0, "dropped_bytes": 0, "kept": 0})
            gone = on_day & dropped
            entry["dropped"] += int(gone.sum())
            entry["dropped_bytes"] += int(nbytes[gone].sum())
            entry["kept"] += int(on_day.sum()) - int(gone.sum())


@dataclass
class ChunkSizer:
    """SQLite: the rows of the next delete chunk, so that a chunk's write transactions (the
    delete, then the incremental vacuum) hold the lock for about `target_ms`. The next size is
    the measured rows per ms times the target, moved at most by a factor of 2 per chunk (one
    slow or quick chunk does not swing it), within [min_rows, max_rows]."""

    rows: int
    target_ms: float
    min_rows: int = 20
    max_rows: int = 100_000

    def __post_init__(self) -> None:
        self.rows = min(self.max_rows, max(self.min_rows, int(self.rows)))

    def update(self, rows_done: int, hold_ms: float) -> int:
        if rows_done > 0:
            ideal = self.rows * 2 if hold_ms <= 0 else rows_done * self.target_ms / hold_ms
            ideal = min(self.rows * 2, max(self.rows / 2, ideal))
            self.rows = int(min(self.max_rows, max(self.min_rows, round(ideal))))
        return self.rows


def _no_progress(fraction: float, message: str) -> None:
    pass


class RetentionBusy(RuntimeError):
    """A second retention run while one is running (on any worker)."""


def run_retention(
    factory: sessionmaker[Session],
    settings,
    *,
    dry_run: bool = False,
    now: float | None = None,
    progress: Progress | None = None,
    job_id: int | None = None,
) -> dict:
    """Apply the policy of `settings` (StorageSettings fields); returns the run's summary.
    One run at a time on a database, whichever worker runs it (RetentionBusy otherwise)."""
    if dry_run:
        return _run_retention(factory, settings, dry_run, now, progress, job_id)
    lock = lock_for(factory.kw["bind"].url.render_as_string(hide_password=False), "retention")
    if not lock.try_acquire():
        raise RetentionBusy(
            "another retention run is in progress (it holds the retention lock); this one did "
            "not start: nothing was dropped"
        )
    try:
        return _run_retention(factory, settings, dry_run, now, progress, job_id)
    finally:
        lock.release()


def _run_retention(factory, settings, dry_run, now, progress, job_id) -> dict:
    progress = progress or _no_progress
    policy = RetentionPolicy.from_settings(settings)
    now = time.time() if now is None else now
    with transaction(factory) as session:
        facts = queries.policy_facts(session, policy, now)
        dialect = session.get_bind().dialect.name
        partitioned = dialect == "postgresql" and partitions.is_partitioned(session.connection())
        if partitioned:
            partitions.ensure_ahead(session.connection(), settings.partitions_ahead_days, now)
        record = RetentionRun(
            dry_run=dry_run,
            job_id=job_id,
            cutoff_ts=facts.cutoff,
            policy=policy.as_dict(),
            status=RETENTION_RUN.initial,
        )
        session.add(record)
        session.flush()
        run_id = record.id
    tally = Tally()
    try:
        if dry_run:
            _chunked(factory, facts, settings, tally, progress, delete=False)
        elif partitioned:
            _partitioned(factory, facts, settings, tally, progress)
        else:
            _chunked(
                factory, facts, settings, tally, progress, delete=True, vacuum=dialect == "sqlite"
            )
    except BaseException as error:
        with transaction(factory) as session:
            record = session.get(RetentionRun, run_id)
            RETENTION_RUN.move(record, RetentionRunStatus.FAILED)
            record.finished_at = datetime.now(UTC)
            record.message = f"{type(error).__name__}: {error}"[:2000]
            _fill(record, tally)
        raise
    verb = "would drop" if dry_run else "dropped"
    kept = ", ".join(f"{n} {r}" for r, n in sorted(tally.kept.items())) or "none"
    cutoff = datetime.fromtimestamp(facts.cutoff, UTC)
    message = (
        f"{verb} {tally.dropped} frames ({tally.dropped_bytes / 1e6:.1f} MB) older than "
        f"{cutoff:%Y-%m-%d %H:%M} UTC; kept {kept}"
    )
    if tally.partitions_dropped:
        message += (
            f"; {len(tally.partitions_dropped)} day partitions trimmed, "
            f"{tally.disk_bytes_freed / 1e6:.1f} MB freed on disk"
        )
    with transaction(factory) as session:
        record = session.get(RetentionRun, run_id)
        RETENTION_RUN.move(record, RetentionRunStatus.DONE)
        record.finished_at, record.message = datetime.now(UTC), message
        _fill(record, tally)
    progress(1.0, message)
    return {
        "summary": message,
        "run_id": run_id,
        "dry_run": dry_run,
        "cutoff_ts": facts.cutoff,
        "dropped_frames": tally.dropped,
        "dropped_bytes": tally.dropped_bytes,
        "kept": dict(tally.kept),
        "partitions_dropped": tally.partitions_dropped,
        "disk_bytes_freed": tally.disk_bytes_freed,
        "chunk_hold_ms": summary_ms(tally.chunk_holds_ms, "chunks"),
    }


def _fill(record: RetentionRun, tally: Tally) -> None:
    record.dropped_frames, record.dropped_bytes = tally.dropped, tally.dropped_bytes
    record.kept = dict(tally.kept)
    record.by_day = tally.by_day
    record.partitions_dropped = list(tally.partitions_dropped)


def _count_candidates(factory, cutoff: float, table: str) -> int:
    with factory() as session:
        return session.execute(
            text(f"SELECT count(*) FROM {table} WHERE robot_id IS NOT NULL AND ts < :c"),
            {"c": cutoff},
        ).scalar_one()


def _chunked(
    factory: sessionmaker[Session],
    facts: PolicyFacts,
    settings,
    tally: Tally,
    progress: Progress,
    *,
    delete: bool,
    vacuum: bool = False,
    table: str = "frames",
    share: tuple[float, float] = (0.0, 1.0),
) -> None:
    pause = settings.retention_chunk_pause_ms / 1000
    sizer = ChunkSizer(
        settings.retention_chunk_rows, getattr(settings, "retention_chunk_hold_ms", 30)
    )
    adaptive = delete and vacuum  # SQLite: the write lock is the whole database's
    total = max(1, _count_candidates(factory, facts.cutoff, table))
    seen, after = 0, 0
    holds = tally.chunk_holds_ms
    while True:
        with factory() as session:  # a read: no write lock (WAL)
            rows = queries.candidate_chunk(session, facts.cutoff, after, sizer.rows, table)
        if not rows:
            break
        ids, video_ids, robot_ids, ts, index, nbytes = _columns(rows)
        codes = facts.reasons(video_ids, robot_ids, ts, index)
        drop = ids[codes == DROPPED_CODE].tolist()
        started = time.perf_counter()
        if delete and drop:
            with transaction(factory) as session:
                queries.delete_frames(session, drop, table)
            if vacuum:
                dropped_bytes = int(nbytes[codes == DROPPED_CODE].sum())
                pages = max(VACUUM_PAGES_PER_CHUNK, 2 * dropped_bytes // SQLITE_PAGE_BYTES)
                _incremental_vacuum(factory, pages)
        hold_ms = (time.perf_counter() - started) * 1000
        tally.add_many(ts, codes, nbytes)  # counted once the chunk committed
        after = int(ids[-1])
        seen += len(rows)
        if adaptive and drop:
            holds.append(hold_ms)
            sizer.update(len(rows), hold_ms)
        progress(
            share[0] + share[1] * min(1.0, seen / total),
            f"{table}: {seen}/{total} old frames checked, {tally.dropped} "
            + ("dropped" if delete else "would go"),
        )
        if delete and pause:
            time.sleep(pause)
    if delete and vacuum:
        _incremental_vacuum(factory, 0)  # what the chunks did not give back yet
    if holds:
        log.info("retention: %s, last chunk size %d", summary_ms(holds, "chunks"), sizer.rows)


def _columns(rows) -> tuple[np.ndarray, ...]:
    """(id, video_id, robot_id, ts, index, bytes) rows as columns; robot ids stay objects."""
    if not rows:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0, dtype=object), np.zeros(0), empty, empty
    ids, video_ids, robot_ids, ts, index, nbytes = zip(*rows, strict=True)
    robots = np.empty(len(robot_ids), dtype=object)
    robots[:] = robot_ids
    return (
        np.array(ids, dtype=np.int64),
        np.array(video_ids, dtype=np.int64),
        robots,
        np.array(ts, dtype=np.float64),
        np.array(index, dtype=np.int64),
        np.array([b or 0 for b in nbytes], dtype=np.int64),
    )


def _incremental_vacuum(factory: sessionmaker[Session], pages: int) -> None:
    """Give up to `pages` free pages (0: all) back to the file system. The statement frees
    one page per step: a script is stepped to its end (a plain execute stops after one)."""
    with transaction(factory) as session:
        driver = session.connection().connection.driver_connection
        driver.executescript(f"PRAGMA incremental_vacuum({int(pages)});")


def _partitioned(
    factory: sessionmaker[Session], facts: PolicyFacts, settings, tally: Tally, progress: Progress
) -> None:
    with factory() as session:
        days = partitions.day_partitions(session.connection())
    old = sorted(d for d in days if partitions.bounds(d)[1] <= facts.cutoff)
    for i, day in enumerate(old):
        name = partitions.partition_name(day)
        progress(0.9 * i / max(1, len(old)), f"partition {name}: choosing the kept frames")
        for attempt in range(TRIM_ATTEMPTS):
            try:
                day_tally = _trim_day(factory, facts, name)
                break
            except OperationalError as error:  # a lock not taken in time: start the day again
                if attempt == TRIM_ATTEMPTS - 1:
                    raise
                log.warning("retention: %s not trimmed (%s); retrying", name, error)
                time.sleep(1 + attempt)
        tally.merge(day_tally)
        if day_tally.dropped:
            tally.partitions_dropped.append(name)
    _chunked(
        factory,
        facts,
        settings,
        tally,
        progress,
        delete=True,
        table=partitions.DEFAULT_PARTITION,
        share=(0.9, 0.1),
    )


def lock_partition(connection: Connection, name: str, mode: str) -> None:
    """LOCK TABLE `name` IN `mode` MODE, each try waiting at most LOCK_TIMEOUT_MS inside a
    savepoint (a try that times out leaves the transaction usable), with a growing pause
    between tries; raises OperationalError when the last try fails."""
    for attempt in range(LOCK_TRIES):
        try:
            with savepoint(connection):
                connection.execute(text(f"SET LOCAL lock_timeout = {LOCK_TIMEOUT_MS}"))
                connection.execute(text(f"LOCK TABLE {name} IN {mode} MODE"))
            return
        except OperationalError:
            if attempt == LOCK_TRIES - 1:
                raise
            time.sleep(min(LOCK_BACKOFF_MAX_S, 0.02 * 1.5**attempt))


def _trim_day(factory: sessionmaker[Session], facts: PolicyFacts, name: str) -> Tally:
    """One day partition left holding only its kept frames, in one transaction (the figures
    count only when it commits)."""
    tally = Tally()
    with transaction(factory) as session:
        connection = session.connection()
        lock_partition(connection, name, "SHARE")  # no frame arrives while the kept are chosen
        before = connection.execute(text(f"SELECT pg_total_relation_size('{name}')")).scalar_one()
        cursor = connection.connection.driver_connection.cursor()
        cursor.execute(
            f'SELECT id, video_id, robot_id, ts, "index", length(keypoints) '
            f"+ coalesce(length(depth), 0) + coalesce(length(floor), 0) "
            f"+ {queries.ROW_OVERHEAD_BYTES} FROM {name}"
        )
        ids, video_ids, robot_ids, ts, index, nbytes = _columns(cursor.fetchall())
        cursor.close()
        codes = facts.reasons(video_ids, robot_ids, ts, index)
        tally.add_many(ts, codes, nbytes)
        if not tally.dropped:
            return tally  # nothing to give back: the partition is left as it is
        kept_ids = ids[codes != DROPPED_CODE].tolist()
        columns = partitions.COLUMNS
        connection.execute(
            text(
                f"CREATE TEMPORARY TABLE retention_kept ON COMMIT DROP AS "
                f"SELECT {columns} FROM {name} WHERE id = ANY(:ids)"
            ),
            {"ids": kept_ids},
        )
        lock_partition(connection, name, "ACCESS EXCLUSIVE")
        connection.execute(text(f"TRUNCATE {name}"))
        connection.execute(
            text(f"INSERT INTO {name} ({columns}) SELECT {columns} FROM retention_kept")
        )
        if after_truncate_hook is not None:
            after_truncate_hook(connection, name)
        after = connection.execute(text(f"SELECT pg_total_relation_size('{name}')")).scalar_one()
        tally.disk_bytes_freed = int(before) - int(after)
    log.info(
        "retention: %s trimmed, %d frames kept, %d dropped", name, len(kept_ids), tally.dropped
    )
    return tally
