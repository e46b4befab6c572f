"""Reads by video prune day partitions (PostgreSQL) through the video's frame time range, every
writer of frames widens that range, and the API's JSON of frame rows is what decoding each
frame gives."""

from __future__ import annotations

import math

import numpy as np
from sqlalchemy import select, text
from sqlalchemy.dialects import postgresql

from backend.db import transaction
from backend.labelling.queries import TIMELINE_COLUMNS, frames_between
from backend.labelling.store import add_video
from backend.models import Frame, Video
from backend.storage import partitions
from backend.storage.frame_reads import json_frames, of_video
from backend.storage.policy import DAY_S
from tests.backend.storage import factories as f
from vigil.skeleton import decode_keypoints, depth_to_json, floor_to_json


def explain(session, statement) -> str:
    sql = statement.compile(dialect=postgresql.dialect(), compile_kwargs={"literal_binds": True})
    return "\n".join(session.execute(text(f"EXPLAIN {sql}")).scalars())


def test_a_read_by_video_touches_only_the_days_of_the_video_and_misses_nothing(pg_factory):
    day = partitions.today() - 10
    with transaction(pg_factory) as session:
        partitions.ensure_partitions(session.connection(), [day - 1, day, day + 1])
        # 23:59:50 .. 00:00:09.5: the video spans midnight, its days are `day` and `day + 1`
        start = (day + 1) * DAY_S - 10
        video = f.robot_video(session, "r1-span", "r1", [start + i / 2 for i in range(40)])
        f.robot_video(session, "r2-before", "r2", [(day - 1) * DAY_S + i for i in range(30)])
        f.robot_video(session, "r3-after", "r3", [(day + 1) * DAY_S + 60 + i for i in range(30)])
        video_id = video.id
    with pg_factory() as session:
        video = session.get(Video, video_id)
        plan = explain(session, select(Frame.index).where(*of_video(session, video)))
        assert partitions.partition_name(day) in plan
        assert partitions.partition_name(day + 1) in plan
        assert partitions.partition_name(day - 1) not in plan
        assert partitions.DEFAULT_PARTITION not in plan
        assert [r.index for r in frames_between(session, video, 0, 99)] == list(range(40))

        video.first_frame_ts = video.last_frame_ts = None  # not known: every partition, still all
        assert partitions.partition_name(day - 1) in explain(
            session, select(Frame.index).where(*of_video(session, video))
        )
        assert [r.index for r in frames_between(session, video, 0, 99)] == list(range(40))
        session.rollback()


def test_sqlite_reads_by_video_id_alone(session_factory):
    with transaction(session_factory) as session:
        video = f.robot_video(session, "r1-t", "r1", [f.NOW + i for i in range(3)])
        clauses = of_video(session, video)
        if session.get_bind().dialect.name == "sqlite":
            assert len(clauses) == 1  # no partitions: the (video_id, index) index as before
        else:
            assert len(clauses) == 2


def test_every_writer_widens_the_range(session_factory):
    with transaction(session_factory) as session:
        times = [f.NOW - 5, f.NOW + 3, f.NOW - 9]
        robot = f.robot_video(session, "r1-t", "r1", times)
        imported = add_video(
            session,
            Video(name="imported", source="openpose", mode="walking", fps=30.0),
            np.ones((3, 25, 3), np.float32),
            [0.5, 0.0, 0.25],
        )
        assert (robot.first_frame_ts, robot.last_frame_ts) == (f.NOW - 9, f.NOW + 3)
        assert (imported.first_frame_ts, imported.last_frame_ts) == (0.0, 0.5)
        robot.cover(f.NOW - 1, f.NOW + 10)
        assert (robot.first_frame_ts, robot.last_frame_ts) == (f.NOW - 9, f.NOW + 10)


def test_json_frames_are_the_values_of_each_frame_decoded(session_factory):
    with transaction(session_factory) as session:
        video = f.robot_video(session, "r1-t", "r1", [f.NOW + i / 10 for i in range(7)])
        frame = session.scalars(
            select(Frame).where(Frame.video_id == video.id, Frame.index == 2)
        ).one()
        frame.depth = np.full(25, np.nan, np.float32).tobytes()  # every depth unknown
        frame.floor = None
        session.flush()
        rows = frames_between(session, video, 0, 6)
        frames = session.scalars(
            select(Frame).where(Frame.video_id == video.id).order_by(Frame.index)
        ).all()
        out = json_frames(rows)
    assert [c.key for c in TIMELINE_COLUMNS] == list(out[0])
    for got, frame in zip(out, frames, strict=True):
        assert got["keypoints"] == decode_keypoints(frame.keypoints).tolist()
        assert got["depth"] == depth_to_json(frame.depth)
        assert got["floor"] == floor_to_json(frame.floor)
        assert (got["index"], got["ts"], got["scores"]) == (frame.index, frame.ts, frame.scores)
    assert out[2]["depth"] == [None] * 25 and out[2]["floor"] is None
    assert out[0]["depth"] is None  # the factory stores no depth on every third frame
    assert not any(isinstance(v, float) and math.isnan(v) for v in out[1]["depth"])
    assert json_frames([]) == []
