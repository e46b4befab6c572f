"""SQL of the storage domain: the facts the retention policy needs, candidate frames, and the
figures of the admin's storage page and /metrics."""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import Integer, and_, cast, func, select, text
from sqlalchemy.orm import Session

from backend.models.alarms import Alarm
from backend.models.annotations import AnnotationSegment, SegmentStatus
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.registry import ModelVersion
from backend.models.storage import FrameArchive, RetentionRun
from backend.models.videos import Frame, Split, Video
from backend.storage import policy as rules
from backend.storage.policy import PolicyFacts, RetentionPolicy

# Rough per-row cost besides the blobs (row header, ids, ts, decision, indexes' entries).
ROW_OVERHEAD_BYTES = 120


def policy_facts(session: Session, policy: RetentionPolicy, now: float) -> PolicyFacts:
    protected: dict[int, str] = {}
    lineage_names: set[str] = set()
    for lineage in session.scalars(select(ModelVersion.lineage)):
        lineage_names.update((lineage or {}).get("training_videos") or [])
    if lineage_names:
        for video_id in session.scalars(select(Video.id).where(Video.name.in_(lineage_names))):
            protected[video_id] = rules.LINEAGE
    for video_id in session.scalars(select(Video.id).where(Video.split != Split.UNASSIGNED)):
        protected[video_id] = rules.SPLIT
    labelled = select(AnnotationSegment.video_id).where(
        AnnotationSegment.status != SegmentStatus.DELETED
    )
    for video_id in session.scalars(labelled.distinct()):
        protected[video_id] = rules.LABELLED
    alarm_rows = [
        (robot_id, first, last, raised.timestamp())
        for robot_id, first, last, raised in session.execute(
            select(Alarm.robot_id, Alarm.first_frame_ts, Alarm.last_frame_ts, Alarm.raised_at)
        )
    ]
    steps = {}
    if policy.downsample_fps > 0:
        steps = {
            video_id: rules.downsample_step(fps, policy.downsample_fps)
            for video_id, fps in session.execute(
                select(Video.id, Video.fps).where(Video.robot_id.is_not(None))
            )
        }
    return PolicyFacts(policy, now, protected, rules.alarm_intervals(alarm_rows, policy), steps)


def _payload_bytes():
    return (
        func.length(Frame.keypoints)
        + func.coalesce(func.length(Frame.depth), 0)
        + func.coalesce(func.length(Frame.floor), 0)
        + ROW_OVERHEAD_BYTES
    )


def candidate_chunk(
    session: Session, cutoff: float, after_id: int, limit: int, table: str = "frames"
) -> list[tuple]:
    """Robot frames older than the cutoff with id > after_id, in id order:
    (id, video_id, robot_id, ts, index, bytes)."""
    rows = session.execute(
        text(
            f'SELECT id, video_id, robot_id, ts, "index", length(keypoints) '
            f"+ coalesce(length(depth), 0) + coalesce(length(floor), 0) + {ROW_OVERHEAD_BYTES} "
            f"FROM {table} WHERE robot_id IS NOT NULL AND ts < :cutoff AND id > :after "
            "ORDER BY id LIMIT :limit"
        ),
        {"cutoff": cutoff, "after": after_id, "limit": limit},
    )
    return [tuple(r) for r in rows]


def delete_frames(session: Session, ids: list[int], table: str = "frames") -> int:
    if not ids:
        return 0
    if session.get_bind().dialect.name == "postgresql":
        result = session.execute(text(f"DELETE FROM {table} WHERE id = ANY(:ids)"), {"ids": ids})
    else:
        placeholders = ", ".join(str(int(i)) for i in ids)
        result = session.execute(text(f"DELETE FROM {table} WHERE id IN ({placeholders})"))
    return result.rowcount


def day_expression():
    return cast(func.floor(Frame.ts / rules.DAY_S), Integer)


def frames_by_day_and_robot(session: Session) -> list[tuple[int, str | None, int, int]]:
    """(UTC day, robot id, frames, bytes) of robot frames; imported recordings (ts not a
    wall-clock time) under robot None and day -1."""
    day = day_expression()
    is_robot = Frame.robot_id.is_not(None)
    rows = session.execute(
        select(
            day,
            Frame.robot_id,
            func.count(),
            func.sum(_payload_bytes()),
        )
        .where(is_robot)
        .group_by(day, Frame.robot_id)
    ).all()
    imported = session.execute(
        select(func.count(), func.sum(_payload_bytes())).where(Frame.robot_id.is_(None))
    ).one()
    out = [(int(d), r, int(n), int(b or 0)) for d, r, n, b in rows]
    if imported[0]:
        out.append((-1, None, int(imported[0]), int(imported[1] or 0)))
    return out


def total_frames(session: Session) -> int:
    return session.scalar(select(func.count()).select_from(Frame)) or 0


def database_bytes(session: Session) -> dict:
    """What the database occupies on disk: SQLite file pages (and free pages), PostgreSQL
    frames' partitions (table, TOAST, indexes)."""
    dialect = session.get_bind().dialect.name
    if dialect == "sqlite":
        page_size = session.execute(text("PRAGMA page_size")).scalar_one()
        pages = session.execute(text("PRAGMA page_count")).scalar_one()
        free = session.execute(text("PRAGMA freelist_count")).scalar_one()
        return {
            "database_bytes": page_size * pages,
            "free_bytes": page_size * free,
            "frames_bytes": None,
        }
    total = session.execute(text("SELECT pg_database_size(current_database())")).scalar_one()
    frames = session.execute(
        text(
            "SELECT coalesce(sum(pg_total_relation_size(i.inhrelid)), 0) FROM pg_inherits i "
            "JOIN pg_class p ON p.oid = i.inhparent WHERE p.relname = 'frames'"
        )
    ).scalar_one()
    if not frames:
        frames = session.execute(text("SELECT pg_total_relation_size('frames')")).scalar_one()
    return {"database_bytes": int(total), "free_bytes": None, "frames_bytes": int(frames)}


def recent_runs(session: Session, limit: int = 20) -> list[RetentionRun]:
    return list(session.scalars(select(RetentionRun).order_by(RetentionRun.id.desc()).limit(limit)))


def last_run(session: Session, dry_run: bool | None = None) -> RetentionRun | None:
    query = select(RetentionRun).where(RetentionRun.status == "done")
    if dry_run is not None:
        query = query.where(RetentionRun.dry_run == dry_run)
    return session.scalars(query.order_by(RetentionRun.id.desc()).limit(1)).first()


def archives(session: Session, limit: int = 200) -> list[FrameArchive]:
    return list(session.scalars(select(FrameArchive).order_by(FrameArchive.id.desc()).limit(limit)))


def archive_by_id(session: Session, archive_id: int) -> FrameArchive | None:
    return session.get(FrameArchive, archive_id)


def video_frames(session: Session, video_id: int) -> list[Frame]:
    return list(
        session.scalars(select(Frame).where(Frame.video_id == video_id).order_by(Frame.index))
    )


def video_segments(session: Session, video_id: int) -> list[AnnotationSegment]:
    return list(
        session.scalars(
            select(AnnotationSegment)
            .where(
                and_(
                    AnnotationSegment.video_id == video_id,
                    AnnotationSegment.status == SegmentStatus.ACCEPTED,
                )
            )
            .order_by(AnnotationSegment.first_frame)
        )
    )


def frame_count(session: Session, video_id: int) -> int:
    return session.scalar(select(func.count()).where(Frame.video_id == video_id)) or 0


def due_retention(session: Session, interval_s: float, now: datetime | None = None) -> bool:
    """Whether a scheduled retention run is due: none queued or running, and the last real run
    (not a dry run) was queued more than interval_s ago, or there was none."""
    active = session.scalar(
        select(Job.id)
        .where(Job.kind == JobKind.RETENTION, Job.status.in_([JobStatus.QUEUED, JobStatus.RUNNING]))
        .limit(1)
    )
    if active is not None:
        return False
    recent = session.execute(
        select(Job.created_at, Job.params)
        .where(Job.kind == JobKind.RETENTION)
        .order_by(Job.id.desc())
        .limit(100)
    ).all()
    now = now or datetime.now(UTC)
    for created_at, params in recent:
        if not (params or {}).get("dry_run"):
            return (now - created_at).total_seconds() >= interval_s
    return True


def last_retention_job(session: Session) -> Job | None:
    """The latest retention job that is not a dry run."""
    for job in session.scalars(
        select(Job).where(Job.kind == JobKind.RETENTION).order_by(Job.id.desc()).limit(100)
    ):
        if not (job.params or {}).get("dry_run"):
            return job
    return None
