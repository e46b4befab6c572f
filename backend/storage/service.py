"""The storage figures (cached: they scan the frames) for the admin page and /metrics, queuing
a retention run, archiving and importing videos. Never commits (the unit of work does)."""

from __future__ import annotations

import threading
import time
from datetime import UTC, datetime, timedelta

from sqlalchemy.orm import Session, sessionmaker

from backend.jobs import queue
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.videos import Video
from backend.storage import archive, partitions, queries
from backend.storage.policy import DAY_S, RetentionPolicy, day_of
from backend.storage.schemas import (
    ArchiveOut,
    DayFigure,
    NextRun,
    RetentionRunOut,
    RobotFigure,
    StorageSummary,
)


def _day_label(day: int) -> str:
    return datetime.fromtimestamp(day * DAY_S, UTC).strftime("%Y-%m-%d")


def summary(session: Session, settings) -> StorageSummary:
    policy = RetentionPolicy.from_settings(settings)
    now = time.time()
    rows = queries.frames_by_day_and_robot(session)
    by_day: dict[int, list[int]] = {}
    by_robot: dict[str | None, list[int]] = {}
    for day, robot_id, frames, nbytes in rows:
        if day >= 0:
            entry = by_day.setdefault(day, [0, 0])
            entry[0] += frames
            entry[1] += nbytes
        robot = by_robot.setdefault(robot_id, [0, 0])
        robot[0] += frames
        robot[1] += nbytes
    days, total_frames, total_bytes = [], 0, 0
    for day in sorted(by_day):
        frames, nbytes = by_day[day]
        total_frames += frames
        total_bytes += nbytes
        days.append(
            DayFigure(
                day=_day_label(day),
                frames=frames,
                bytes=nbytes,
                cumulative_frames=total_frames,
                cumulative_bytes=total_bytes,
            )
        )
    robots = [
        RobotFigure(robot_id=r, frames=v[0], bytes=v[1])
        for r, v in sorted(by_robot.items(), key=lambda kv: -kv[1][1])
    ]
    due = _next_due(session, settings)
    at = due.timestamp() if due else now
    cutoff = day_of(policy.cutoff(at)) * DAY_S
    older = [(f, b) for d, (f, b) in by_day.items() if (d + 1) * DAY_S <= cutoff]
    preview = queries.last_run(session, dry_run=True)
    disk = queries.database_bytes(session)
    dialect = session.get_bind().dialect.name
    n_partitions = None
    if dialect == "postgresql" and partitions.is_partitioned(session.connection()):
        n_partitions = len(partitions.day_partitions(session.connection()))
    return StorageSummary(
        dialect=dialect,
        computed_at=datetime.now(UTC),
        total_frames=sum(v[0] for v in by_robot.values()),
        payload_bytes=sum(v[1] for v in by_robot.values()),
        database_bytes=disk["database_bytes"],
        frames_bytes=disk["frames_bytes"],
        free_bytes=disk["free_bytes"],
        partitions=n_partitions,
        days=days,
        robots=robots,
        policy=policy.as_dict() | {"interval_h": settings.retention_interval_h},
        next_run=NextRun(
            due_at=due,
            cutoff_ts=cutoff,
            older_frames=sum(f for f, _ in older),
            older_bytes=sum(b for _, b in older),
            preview=RetentionRunOut.model_validate(preview) if preview else None,
        ),
        runs=[RetentionRunOut.model_validate(r) for r in queries.recent_runs(session)],
        archives=len(queries.archives(session, limit=100_000)),
    )


def _next_due(session: Session, settings) -> datetime | None:
    last = queries.last_retention_job(session)
    if last is None:
        return datetime.now(UTC)
    if last.status in (JobStatus.QUEUED, JobStatus.RUNNING):
        return None
    return max(datetime.now(UTC), last.created_at + timedelta(hours=settings.retention_interval_h))


class SummaryCache:
    """One summary per `ttl_s` for /metrics and the page (the figures scan every frame)."""

    def __init__(self, ttl_s: float = 60.0) -> None:
        self.ttl_s = ttl_s
        self._lock = threading.Lock()
        self._value: StorageSummary | None = None
        self._at = 0.0

    def get(self, factory: sessionmaker[Session], settings, fresh: bool = False) -> StorageSummary:
        with self._lock:
            if fresh or self._value is None or time.monotonic() - self._at > self.ttl_s:
                with factory() as session:
                    self._value = summary(session, settings)
                self._at = time.monotonic()
            return self._value

    def latest(self, factory: sessionmaker[Session], settings) -> StorageSummary | None:
        """The last figures without waiting (a /metrics scrape must not scan the frames): a
        stale or missing value is refreshed in a background thread for the next call."""
        stale = self._value is None or time.monotonic() - self._at > self.ttl_s
        if stale and self._lock.acquire(blocking=False):
            self._lock.release()
            threading.Thread(target=self.get, args=(factory, settings), daemon=True).start()
        return self._value


def queue_retention(session: Session, dry_run: bool, user_id: int | None) -> Job:
    return queue.enqueue(session, JobKind.RETENTION, {"dry_run": dry_run}, created_by_id=user_id)


def archive_out(session: Session, found) -> ArchiveOut:
    out = ArchiveOut.model_validate(found)
    if found.video_id is not None:
        out.frames_in_database = queries.frame_count(session, found.video_id)
    return out


def make_archives(
    session: Session, settings, video_id: int | None, transport_id: str | None, user_id: int | None
) -> list:
    if video_id is not None:
        video = session.get(Video, video_id)
        if video is None:
            raise archive.ArchiveError(f"video {video_id} not found")
        return [archive.export_video(session, video, settings.archive_dir, user_id)]
    return archive.export_transport(session, transport_id, settings.archive_dir, user_id)
