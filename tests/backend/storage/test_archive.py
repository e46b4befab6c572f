"""Parquet archive round trip: a video exported, its frames dropped, imported again is bit for
bit what it was (every blob, float, decision and score), with its segments; the manifest's
sha256 is checked; re-exporting gives the same table."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from sqlalchemy import delete, select

from backend.db import transaction
from backend.models import AnnotationSegment, Frame, FrameArchive, Video
from backend.storage import archive
from tests.backend.storage import factories as f

COLUMNS = [c.key for c in Frame.__table__.columns if c.key not in ("id", "video_id")]


def stored(session, video_id: int) -> list[tuple]:
    frames = session.scalars(
        select(Frame).where(Frame.video_id == video_id).order_by(Frame.index)
    ).all()
    return [tuple(getattr(fr, c) for c in COLUMNS) for fr in frames]


def test_parquet_round_trip_is_bit_identical(database_url, session_factory, tmp_path):
    with transaction(session_factory) as session:
        video = f.robot_video(
            session, "r1-transport", "r1", [f.NOW - 90 + i / 7 for i in range(40)]
        )
        f.label(session, video, 5, 14, "falling")
        frame = session.scalars(
            select(Frame).where(Frame.video_id == video.id, Frame.index == 3)
        ).one()
        frame.scores = {"emergency": 0.1 + 0.2, "normal": 1 / 3}  # floats that print long
        frame.shadow_decision, frame.shadow_scores = "emergency", {"emergency": 0.7}
        frame.threshold = 0.123456789012345
        video_id = video.id
    with transaction(session_factory) as session:
        original = stored(session, video_id)
        made = archive.export_video(session, session.get(Video, video_id), tmp_path)
        archive_id, path = made.id, Path(made.path)
    manifest = json.loads(Path(made.manifest_path).read_text())
    assert manifest["sha256"] == archive.sha256_of(path) and manifest["frames"] == 40
    assert manifest["labelled_frames"] == 10
    assert pq.read_table(path).column("label").to_pylist()[5:15] == ["falling"] * 10

    with transaction(session_factory) as session:  # retention dropped the frames and labels
        session.execute(delete(Frame).where(Frame.video_id == video_id))
        session.execute(delete(AnnotationSegment).where(AnnotationSegment.video_id == video_id))
        dropped = session.get(Video, video_id)
        dropped.first_frame_ts = dropped.last_frame_ts = None  # a range the import must restore
    with transaction(session_factory) as session:
        archive.import_archive(session, session.get(FrameArchive, archive_id))
    with transaction(session_factory) as session:
        assert stored(session, video_id) == original
        back = session.get(Video, video_id)
        assert (back.first_frame_ts, back.last_frame_ts) == (f.NOW - 90, f.NOW - 90 + 39 / 7)
        query = select(AnnotationSegment).where(AnnotationSegment.video_id == video_id)
        segments = session.scalars(query).all()
        assert [(s.first_frame, s.last_frame, s.label_key) for s in segments] == [
            (5, 14, "falling")
        ]
        archive.import_archive(session, session.get(FrameArchive, archive_id))  # idempotent
    with transaction(session_factory) as session:
        assert stored(session, video_id) == original
        again = archive.export_video(session, session.get(Video, video_id), tmp_path / "again")
    assert pq.read_table(again.path).equals(pq.read_table(path))
    assert again.sha256 == made.sha256


def test_import_refuses_a_file_that_does_not_match_its_sha256(
    database_url, session_factory, tmp_path
):
    with transaction(session_factory) as session:
        video = f.robot_video(session, "r2-transport", "r2", [f.NOW + i for i in range(3)])
        made = archive.export_video(session, video, tmp_path)
        made.sha256 = "0" * 64
        with pytest.raises(archive.ArchiveError, match="sha256"):
            archive.import_archive(session, made)


def test_archive_labels_overlapping_segments_as_the_export_does(session_factory, tmp_path):
    """One rule turns segments into per-frame labels (`vigil.segments`): where accepted segments
    overlap, the archive's label column equals the CSV export's labels row by row (the segment
    updated last wins, here the one that starts first), also after the archive is imported
    again."""
    from datetime import timedelta

    from backend.labelling.export import export_csv

    with transaction(session_factory) as session:
        video = f.robot_video(session, "r3-transport", "r3", [f.NOW + i / 10 for i in range(30)])
        f.label(session, video, 2, 20, "walking")
        f.label(session, video, 10, 25, "falling")
        first, second = session.scalars(
            select(AnnotationSegment)
            .where(AnnotationSegment.video_id == video.id)
            .order_by(AnnotationSegment.first_frame)
        ).all()
        first.updated_at = second.updated_at + timedelta(minutes=5)  # edited last: it wins
        video_id = video.id

    def exported(session) -> list[str | None]:
        rows = export_csv(session, session.get(Video, video_id)).splitlines()[1:]
        return [row.split(",")[3] or None for row in rows]

    with transaction(session_factory) as session:
        made = archive.export_video(session, session.get(Video, video_id), tmp_path)
        archive_id, expected = made.id, exported(session)
    labels = pq.read_table(made.path).column("label").to_pylist()
    assert labels == expected
    assert labels[10:21] == ["walking"] * 11 and labels[21:26] == ["falling"] * 5

    with transaction(session_factory) as session:  # frames and labels dropped, then restored
        session.execute(delete(Frame).where(Frame.video_id == video_id))
        session.execute(delete(AnnotationSegment).where(AnnotationSegment.video_id == video_id))
    with transaction(session_factory) as session:
        archive.import_archive(session, session.get(FrameArchive, archive_id))
    with transaction(session_factory) as session:
        assert exported(session) == expected
        again = archive.export_video(session, session.get(Video, video_id), tmp_path / "again")
    assert pq.read_table(again.path).column("label").to_pylist() == expected
