"""The ingest keeps each video's frame time range (videos.first_frame_ts / last_frame_ts) over
every frame it stores, across flushes and clock steps, so reads that prune by it miss nothing."""

from __future__ import annotations

import json

from sqlalchemy import select

from backend.models import Frame, Role, Video
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from vigil.protocol import FrameBatch, Hello


def send(ws, records) -> dict:
    ws.send_text(FrameBatch(frames=records).model_dump_json())
    return json.loads(ws.receive_text())


def at(seq: int, ts: float):
    return frame(seq).model_copy(update={"ts": ts})


def test_range_covers_every_frame_across_flushes_and_a_clock_step(
    client, make_account, robot, session_factory
):
    engineer = make_account(Role.ENGINEER, ward=None, username="eve")
    t = 1_900_000_000.0
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        ws.receive_text()
        assert send(ws, [at(1, t), at(2, t + 0.1), at(3, t + 0.2)])["type"] == "ack"
        # the robot's clock steps back, then forward: a later flush, another writer path
        assert send(ws, [at(4, t - 100.0), at(5, t + 50.0)])["type"] == "ack"

    with session_factory() as session:
        video = session.scalars(select(Video).where(Video.robot_id == robot)).one()
        stamps = session.scalars(select(Frame.ts).where(Frame.video_id == video.id)).all()
        assert (video.first_frame_ts, video.last_frame_ts) == (min(stamps), max(stamps))
        assert (video.first_frame_ts, video.last_frame_ts) == (t - 100.0, t + 50.0)
    timeline = client.get(f"/api/videos/{video.id}/frames", headers=engineer.headers)
    assert [f["seq"] for f in timeline.json()] == [1, 2, 3, 4, 5]
