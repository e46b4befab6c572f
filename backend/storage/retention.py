"""One retention run: apply the policy (backend/storage/policy.py) and record what it dropped,
how much, and what it kept and why (a `retention_runs` row). A dry run records the same
figures without dropping anything.

SQLite: frames are deleted in bounded chunks (each its own short transaction, then
`PRAGMA incremental_vacuum` gives the pages back and a pause lets ingest commit), so the write
lock is never held long enough to delay an acknowledgement.
PostgreSQL: each day partition entirely older than the cutoff is replaced by one holding only the
kept frames, then dropped (backend/storage/partitions.py); the default partition is deleted from
in chunks. Never a DELETE over the whole table.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime

from sqlalchemy import text
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.models.storage import RetentionRun, RetentionRunStatus
from backend.storage import partitions, queries
from backend.storage.policy import PolicyFacts, RetentionPolicy, day_of
from vigil.states import StateMachine

log = logging.getLogger(__name__)

Progress = Callable[[float, str], None]
VACUUM_PAGES_PER_CHUNK = 512
SWAP_ATTEMPTS = 5

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

    def merge(self, other: Tally) -> None:
        self.dropped += other.dropped
        self.dropped_bytes += other.dropped_bytes
        self.kept.update(other.kept)
        self.disk_bytes_freed += other.disk_bytes_freed
        for day, entry in other.by_day.items():
            mine = self.by_day.setdefault(day, {"dropped": 0, "dropped_bytes": 0, "kept": 0})
            for key, value in entry.items():
                mine[key] += value

    def add(self, ts: float, reason: str | None, nbytes: int) -> None:
        day = datetime.fromtimestamp(day_of(ts) * 86400, UTC).strftime("%Y-%m-%d")
        entry = self.by_day.setdefault(day, {"dropped": 0, "dropped_bytes": 0, "kept": 0})
        if reason is None:
            self.dropped += 1
            self.dropped_bytes += nbytes
            entry["dropped"] += 1
            entry["dropped_bytes"] += nbytes
        else:
            self.kept[reason] += 1
            entry["kept"] += 1


def _no_progress(fraction: float, message: str) -> None:
    pass


def run_retention(
    factory: sessionmaker[Session],
    settings,
    *,
    dry_run: bool = False,
    now: float | None = None,
    progress: Progress | None = None,
    job_id: int | None = None,
) -> dict:
    """Apply the policy of `settings` (StorageSettings fields); returns the run's summary."""
    progress = progress or _no_progress
    policy = RetentionPolicy.from_settings(settings)
    now = time.time() if now is None else now
    with transaction(factory) as session:
        facts = queries.policy_facts(session, policy, now)
        dialect = session.get_bind().dialect.name
        partitioned = dialect == "postgresql" and partitions.is_partitioned(session.connection())
        if partitioned:
            partitions.ensure_ahead(session.connection(), settings.partitions_ahead_days, now)
        record = RetentionRun(dry_run=dry_run, job_id=job_id, cutoff_ts=facts.cutoff,
                              policy=policy.as_dict(), status=RETENTION_RUN.initial)  # fmt: skip
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
            _chunked(factory, facts, settings, tally, progress, delete=True,
                     vacuum=dialect == "sqlite")  # fmt: skip
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
    message = (f"{verb} {tally.dropped} frames ({tally.dropped_bytes / 1e6:.1f} MB) older than "
               f"{cutoff:%Y-%m-%d %H:%M} UTC; kept {kept}")  # fmt: skip
    if tally.partitions_dropped:
        message += (f"; {len(tally.partitions_dropped)} day partitions replaced, "
                    f"{tally.disk_bytes_freed / 1e6:.1f} MB freed on disk")  # fmt: skip
    with transaction(factory) as session:
        record = session.get(RetentionRun, run_id)
        RETENTION_RUN.move(record, RetentionRunStatus.DONE)
        record.finished_at, record.message = datetime.now(UTC), message
        _fill(record, tally)
    progress(1.0, message)
    return {"summary": message, "run_id": run_id, "dry_run": dry_run, "cutoff_ts": facts.cutoff,
            "dropped_frames": tally.dropped, "dropped_bytes": tally.dropped_bytes,
            "kept": dict(tally.kept), "partitions_dropped": tally.partitions_dropped,
            "disk_bytes_freed": tally.disk_bytes_freed}  # fmt: skip


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
    chunk, pause = settings.retention_chunk_rows, settings.retention_chunk_pause_ms / 1000
    total = max(1, _count_candidates(factory, facts.cutoff, table))
    seen, after = 0, 0
    while True:
        with transaction(factory) as session:
            rows = queries.candidate_chunk(session, facts.cutoff, after, chunk, table)
            if not rows:
                break
            drop = []
            for frame_id, video_id, robot_id, ts, index, nbytes in rows:
                reason = facts.reason(video_id, robot_id, ts, index)
                tally.add(ts, reason, nbytes or 0)
                if reason is None:
                    drop.append(frame_id)
            if delete:
                queries.delete_frames(session, drop, table)
        after = rows[-1][0]
        seen += len(rows)
        if delete and vacuum:
            _incremental_vacuum(factory, VACUUM_PAGES_PER_CHUNK)
        progress(share[0] + share[1] * min(1.0, seen / total),
                 f"{table}: {seen}/{total} old frames checked, {tally.dropped} "
                 + ("dropped" if delete else "would go"))  # fmt: skip
        if delete and pause:
            time.sleep(pause)
    if delete and vacuum:
        _incremental_vacuum(factory, 0)  # what the chunks did not give back yet


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
        for attempt in range(SWAP_ATTEMPTS):
            try:
                kept = _swap_day(factory, facts, day, name)
                break
            except OperationalError as error:  # lock_timeout: ingest held the parent; retry
                if attempt == SWAP_ATTEMPTS - 1:
                    raise
                log.warning("retention: %s swap waited too long (%s); retrying", name, error)
                time.sleep(1 + attempt)
        tally.merge(kept)
        tally.partitions_dropped.append(name)
    _chunked(factory, facts, settings, tally, progress, delete=True,
             table=partitions.DEFAULT_PARTITION, share=(0.9, 0.1))  # fmt: skip


def _swap_day(factory: sessionmaker[Session], facts: PolicyFacts, day: int, name: str) -> Tally:
    """One day partition replaced by its kept frames, in one transaction (the figures count
    only when it commits)."""
    tally = Tally()
    with transaction(factory) as session:
        connection = session.connection()
        connection.execute(text(f"LOCK TABLE {name} IN SHARE MODE"))
        kept_ids = []
        result = connection.execute(
            text(
                f'SELECT id, video_id, robot_id, ts, "index", length(keypoints) '
                f"+ coalesce(length(depth), 0) + coalesce(length(floor), 0) "
                f"+ {queries.ROW_OVERHEAD_BYTES} FROM {name}"
            ).execution_options(stream_results=True, yield_per=20000)
        )
        for frame_id, video_id, robot_id, ts, index, nbytes in result:
            reason = facts.reason(video_id, robot_id, ts, index)
            tally.add(ts, reason, nbytes or 0)
            if reason is not None:
                kept_ids.append(frame_id)
        tally.disk_bytes_freed += partitions.replace_day_keeping(connection, day, kept_ids)
    log.info("retention: %s replaced, %d frames kept", name, len(kept_ids))
    return tally
