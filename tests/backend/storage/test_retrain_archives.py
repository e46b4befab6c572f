"""Retrain's archived videos: the re-imported frames are committed, not lost with a read
session (issue 35: `with_archived` wrote inside `context.read()`)."""

from __future__ import annotations

from sqlalchemy import delete, func, select

from backend.db import transaction
from backend.models import AnnotationSegment, Frame, Video
from backend.storage import archive
from tests.backend.storage import factories as f
from worker.context import JobContext
from worker.jobs.retrain import restore_archives
from worker.settings import WorkerSettings


def test_restored_archive_frames_outlive_the_step(database_url, session_factory, tmp_path):
    with transaction(session_factory) as session:
        video = f.robot_video(session, "r1-t", "r1", [f.NOW - 90 + i / 7 for i in range(40)])
        f.label(session, video, 5, 14, "falling")
        video_id = video.id
    with transaction(session_factory) as session:
        archive_id = archive.export_video(session, session.get(Video, video_id), tmp_path).id
    with transaction(session_factory) as session:  # retention dropped the frames and labels
        session.execute(delete(Frame).where(Frame.video_id == video_id))
        session.execute(delete(AnnotationSegment).where(AnnotationSegment.video_id == video_id))

    context = JobContext(
        job_id=1,
        params={},
        created_by_id=None,
        factory=session_factory,
        settings=WorkerSettings(),
        worker_id="test",
    )
    with context.write() as session:
        assert restore_archives(session, [archive_id]) == [video_id]
    # A new session sees them: before the fix the import ran in a read session and vanished.
    with session_factory() as session:
        count = select(func.count()).select_from(Frame).where(Frame.video_id == video_id)
        assert session.scalar(count) == 40
        segments = select(func.count()).where(AnnotationSegment.video_id == video_id)
        assert session.scalar(segments) == 1
