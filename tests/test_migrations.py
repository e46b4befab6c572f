"""Migrations on the test database kind (throwaway database): upgrade from empty to head
matches the models, downgrade goes back to empty, and 0002 can be undone and redone; 0009
merges a database built by the old double URFD import."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect

from backend import models  # noqa: F401  (registers every table)
from backend.db import Base, make_engine
from backend.migrate import downgrade, upgrade
from backend.storage import partitions
from tests.conftest import create_throwaway_database
from tests.conftest import test_database_kind as database_kind


@pytest.fixture
def empty_database_url(tmp_path) -> Iterator[str]:
    if database_kind() == "postgresql":
        url, drop = create_throwaway_database("vigil_migrations")
        yield url
        drop()
    else:
        yield f"sqlite:///{tmp_path / 'migrations.db'}"


def tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names())
    finally:
        engine.dispose()


def schema_differences(url: str) -> list:
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            opts = {"compare_type": False}
            if connection.dialect.name == "postgresql":
                opts["include_object"] = partitions.include_object  # frames: day partitions
            context = MigrationContext.configure(connection, opts=opts)
            return compare_metadata(context, Base.metadata)
    finally:
        engine.dispose()


def transport_columns(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return {c["name"] for c in inspect(engine).get_columns("transports")}
    finally:
        engine.dispose()


def test_upgrade_from_empty_matches_the_models_and_downgrade_returns_to_empty(
    empty_database_url,
):
    url = empty_database_url
    assert tables(url) == set()
    upgrade(url)
    assert set(Base.metadata.tables) <= tables(url)
    assert schema_differences(url) == []

    downgrade(url, "0001")
    assert "last_frame_at" not in transport_columns(url)
    upgrade(url)
    assert "last_frame_at" in transport_columns(url)
    assert schema_differences(url) == []

    downgrade(url, "base")
    assert tables(url) <= {"alembic_version"}


# --- 0009_urfd_dedup: a database built by the old double URFD import -------------------------

#: The worker importer's fine-label map before 0009 (the one map is vigil.datasets.urfd's).
OLD_WORKER_MAP = {
    "fall": {0: "falling", 1: "lying_on_floor", -1: "standing"},
    "adl": {0: "sitting_down", 1: "lying_down_deliberately", -1: "walking"},
}


def _old_worker_import(session, names: list[str]) -> dict[str, int]:
    """What worker.db_data.import_urfd wrote before 0009 (the second URFD import of `make
    run`): videos named urfd/<sequence> with the worker's own fine-label map, no depth."""
    from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
    from backend.models.videos import Frame, Video
    from vigil.datasets import urfd
    from vigil.segments import label_runs
    from vigil.skeleton import encode_floor, encode_keypoints

    ids = {}
    for seq in urfd.load(None, names):
        split = "test" if urfd.is_gold(seq.name) else "train"
        video = Video(
            name=f"urfd/{seq.name}",
            source="urfd",
            generated=False,
            mode="walking",
            camera="kinect-cam0",
            fps=urfd.FPS,
            frame_count=len(seq),
            split=split,
        )
        session.add(video)
        session.flush()
        rows = zip(seq.keypoints, seq.timestamps, seq.floor, strict=True)
        session.execute(
            Frame.__table__.insert(),
            [
                {
                    "video_id": video.id,
                    "index": i,
                    "ts": float(t),
                    "keypoints": encode_keypoints(k),
                    "floor": encode_floor(f),
                }
                for i, (k, t, f) in enumerate(rows)
            ],
        )
        kind = seq.name.split("-")[0]
        fine = [None if np.isnan(v) else OLD_WORKER_MAP[kind][int(v)] for v in seq.urfd_label]
        for first, last, key in label_runs(fine):
            session.add(
                AnnotationSegment(
                    video_id=video.id,
                    first_frame=first,
                    last_frame=last,
                    label_key=key,
                    taxonomy_version=1,
                    status=SegmentStatus.ACCEPTED,
                    source=SegmentSource.IMPORT,
                )
            )
        ids[seq.name] = video.id
    session.flush()
    return ids


def test_0009_merges_the_double_urfd_import_without_losing_what_people_made(
    empty_database_url,
):
    from sqlalchemy import func, select

    from backend.db import make_session_factory, transaction
    from backend.labelling.importers.urfd import import_urfd
    from backend.models import Alarm, AnnotationSegment, Frame, Job, Robot, User, Video
    from backend.models.users import Role
    from vigil.datasets import urfd
    from vigil.segments import label_runs

    both, only_copy = ["fall-01", "fall-05", "adl-01"], "adl-11"
    url = empty_database_url
    upgrade(url)
    engine = make_engine(url)
    factory = make_session_factory(engine)
    with transaction(factory) as session:
        kept = {v.name: v.id for v in import_urfd(session, names=both).videos}
        copies = _old_worker_import(session, [*both, only_copy])
        annotator = User(username="ann", password_hash="x", role=Role.ANNOTATOR)
        session.add_all([annotator, Robot(id="r1", ward="w")])
        session.flush()
        # What people made on the copies: a segment, a review of an import segment, an alarm
        # clip, a split, a queued job naming a copy, a job result naming copies.
        session.add(
            AnnotationSegment(
                video_id=copies["fall-01"],
                first_frame=3,
                last_frame=9,
                label_key="stumbling",
                taxonomy_version=1,
                status="submitted",
                source="annotator",
                annotator_id=annotator.id,
            )
        )
        reviewed = session.scalars(
            select(AnnotationSegment)
            .where(AnnotationSegment.video_id == copies["fall-05"])
            .order_by(AnnotationSegment.first_frame)
        ).first()
        assert reviewed.label_key == "standing"
        reviewed.reviewer_id, reviewed_id = annotator.id, reviewed.id
        alarm = Alarm(
            kind="emergency", priority="high", robot_id="r1", ward="w", video_id=copies["adl-01"]
        )
        session.add(alarm)
        session.get(Video, copies["adl-01"]).split = "unassigned"  # an admin's choice
        names = ["urfd/fall-01", f"urfd/{only_copy}", "urfd/other"]
        job = Job(
            kind="retrain",
            status="queued",
            params={"video_ids": [copies["fall-01"], 999]},
            result={"training_videos": names},
        )
        session.add(job)
        session.flush()
        alarm_id, job_id = alarm.id, job.id
        # fall-01 as imported by a version without floor measures: the copy has them.
        session.execute(
            Frame.__table__.update().where(Frame.video_id == kept["fall-01"]).values(floor=None)
        )
    # The database was built at head; run 0009 on it as on an existing database.
    downgrade(url, "0008_sessions")
    upgrade(url)
    upgrade(url)  # nothing left to merge

    sequences = {s.name: s for s in urfd.load(None, [*both, only_copy])}
    with factory() as session:
        videos = {v.name: v for v in session.scalars(select(Video).where(Video.source == "urfd"))}
        assert sorted(videos) == sorted(sequences)  # one video per recording
        assert {name: videos[name].id for name in both} == kept
        assert videos[only_copy].id == copies[only_copy]  # renamed
        for name, video in videos.items():
            count = session.scalar(select(func.count()).where(Frame.video_id == video.id))
            assert count == len(sequences[name])
        total = session.scalar(select(func.count()).select_from(Frame))
        assert total == sum(len(s) for s in sequences.values())
        floors = select(Frame.floor).where(
            Frame.video_id == kept["fall-01"], Frame.floor.is_not(None)
        )
        assert session.scalars(floors).first() is not None

        def segments(name, source="import"):
            query = select(AnnotationSegment).where(
                AnnotationSegment.video_id == videos[name].id, AnnotationSegment.source == source
            )
            rows = session.scalars(query.order_by(AnnotationSegment.first_frame)).all()
            return [(s.first_frame, s.last_frame, s.label_key) for s in rows if s.id != reviewed_id]

        for name, sequence in sequences.items():  # one set of import segments, by the one map
            assert segments(name) == label_runs(sequence.truth()), name
        assert "bending" in {label for _, _, label in segments(only_copy)}
        assert segments("fall-01", "annotator") == [(3, 9, "stumbling")]
        moved = session.get(AnnotationSegment, reviewed_id)
        assert (moved.video_id, moved.label_key) == (kept["fall-05"], "walking")
        assert moved.reviewer_id is not None
        assert session.get(Alarm, alarm_id).video_id == kept["adl-01"]
        assert videos["adl-01"].split == "unassigned"
        assert videos[only_copy].split == videos["fall-01"].split == "train"
        assert videos["fall-05"].split == "test"
        job = session.get(Job, job_id)
        assert job.params["video_ids"] == [kept["fall-01"], 999]
        assert job.result["training_videos"] == ["fall-01", only_copy, "urfd/other"]
    engine.dispose()


# --- 0012_video_frame_range: the range filled from the frames already stored -----------------


def test_0012_fills_each_video_frame_range_from_its_frames(empty_database_url):
    from sqlalchemy import text

    url = empty_database_url
    upgrade(url, "0011_frame_storage")
    engine = make_engine(url)
    try:
        with engine.begin() as connection:
            for name in ("with-frames", "without-frames"):
                connection.execute(
                    text(
                        "INSERT INTO videos (name, source, generated, mode, fps, split, "
                        "frame_count, rgb_frame_offset, created_at) VALUES (:n, 'urfd', false, "
                        "'walking', 30, 'train', 3, 0, CURRENT_TIMESTAMP)"
                    ),
                    {"n": name},
                )
            video_id = connection.execute(
                text("SELECT id FROM videos WHERE name = 'with-frames'")
            ).scalar_one()
            for index, ts in enumerate([1_700_000_000.5, 2.25, 1_700_000_100.0]):
                connection.execute(
                    text(
                        'INSERT INTO frames (video_id, "index", ts, keypoints) '
                        "VALUES (:v, :i, :t, :k)"
                    ),
                    {"v": video_id, "i": index, "t": ts, "k": b"\0" * 300},
                )
        upgrade(url)
        with engine.connect() as connection:
            ranges = dict(
                (name, (first, last))
                for name, first, last in connection.execute(
                    text("SELECT name, first_frame_ts, last_frame_ts FROM videos")
                )
            )
        assert ranges == {"with-frames": (2.25, 1_700_000_100.0), "without-frames": (None, None)}
    finally:
        engine.dispose()
    downgrade(url, "0011_frame_storage")
    assert "first_frame_ts" not in {c["name"] for c in inspect_columns(url, "videos")}


def inspect_columns(url: str, table: str) -> list[dict]:
    engine = make_engine(url)
    try:
        return inspect(engine).get_columns(table)
    finally:
        engine.dispose()
