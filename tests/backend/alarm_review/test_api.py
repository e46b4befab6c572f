"""Alarm review over HTTP: a robot falls, the nurse resolves it as a false alarm, and the replay,
history, fatigue statistics and the annotators' review queue show it."""

from __future__ import annotations

import json
import time

import numpy as np
from sqlalchemy import select

from backend.db import transaction
from backend.models import AnnotationSegment, Role, Video
from tests.backend.conftest import ROBOT_TOKEN
from tests.browser.simulated_robot import fall_frames
from vigil.protocol import FrameBatch, Hello, TransportStart


def _fall(client, robot: str) -> None:
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        ws.receive_text()
        start = TransportStart(
            transport_id="t-9", mode="walking", patient="P-3", location="lift 2", ts=time.time()
        )
        ws.send_text(start.model_dump_json())
        frames = fall_frames(0, time.time() - 5, "t-9")
        for i in range(0, len(frames), 10):
            ws.send_text(FrameBatch(frames=frames[i : i + 10]).model_dump_json())
            assert json.loads(ws.receive_text())["type"] == "ack"


def test_resolved_false_alarm_flows_into_replay_history_fatigue_and_review(
    client, make_account, robot, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="nina")
    annotator = make_account(Role.ANNOTATOR, ward=None, username="anna")
    _fall(client, robot)
    [alarm] = client.get("/api/alarms", headers=nurse.headers).json()
    assert alarm["kind"] == "emergency"

    replay = client.get(
        f"/api/alarms/{alarm['id']}/replay?before_s=3&after_s=1", headers=nurse.headers
    ).json()
    seqs = [f["seq"] for f in replay["frames"]]
    assert seqs == sorted(seqs) and alarm["first_seq"] in seqs
    assert seqs[0] <= alarm["first_seq"] - 25  # 3 s before at 10 fps, minus rounding
    assert len(replay["frames"][0]["keypoints"]) == 25
    assert set(replay["frames"][0]["scores"]) == {"normal", "emergency"}
    assert replay["generated"] is False
    with transaction(session_factory) as session:
        session.get(Video, alarm["video_id"]).generated = True
    replay_url = f"/api/alarms/{alarm['id']}/replay"
    assert client.get(replay_url, headers=nurse.headers).json()["generated"] is True

    client.post(f"/api/alarms/{alarm['id']}/acknowledge", headers=nurse.headers)
    resolved = client.post(
        f"/api/alarms/{alarm['id']}/resolve",
        json={"verdict": "false_alarm", "reason": "bending", "comment": "picked up a glove"},
        headers=nurse.headers,
    )
    assert resolved.status_code == 200, resolved.text

    with session_factory() as session:
        segment = session.scalars(select(AnnotationSegment)).one()
        first = replay["frames"][seqs.index(alarm["first_seq"])]["index"]
        last_seq = resolved.json()["last_seq"]
        assert (segment.first_frame - first, segment.last_frame - segment.first_frame) == (
            0,
            last_seq - alarm["first_seq"],
        )
        assert (segment.label_key, segment.status, segment.model_version) == (
            "bending",
            "pending",
            "sim-1",
        )

    queue = client.get("/api/review-queue", headers=annotator.headers).json()
    assert [item["alarm_id"] for item in queue] == [alarm["id"]]

    history = client.get("/api/alarm-history?verdict=false_alarm", headers=nurse.headers).json()
    assert history["total"] == 1 and history["items"][0]["id"] == alarm["id"]
    assert (
        client.get("/api/alarm-history?verdict=unsure", headers=nurse.headers).json()["total"] == 0
    )

    fatigue = client.get("/api/alarm-fatigue", headers=nurse.headers).json()
    assert sum(s["alarms"] for s in fatigue["shifts"]) == 1
    [model] = fatigue["by_model"]
    assert (model["model_version"], model["false_share"]) == ("sim-1", 1.0)
    assert model["median_ack_s"] is not None


def test_review_endpoints_check_role_and_ward(client, make_account, robot):
    nurse_b = make_account(Role.NURSE, ward="ward-b", username="bea")
    annotator = make_account(Role.ANNOTATOR, ward=None, username="ann")
    _fall(client, robot)
    assert client.get("/api/alarm-history", headers=annotator.headers).status_code == 403
    assert client.get("/api/review-queue", headers=nurse_b.headers).status_code == 403
    assert client.get("/api/alarm-history", headers=nurse_b.headers).json()["total"] == 0
    forbidden = client.get("/api/alarm-history?ward=ward-a", headers=nurse_b.headers)
    assert forbidden.status_code == 403 and "ward-a" in forbidden.json()["detail"]
    assert client.get("/api/alarms/1/replay", headers=nurse_b.headers).status_code == 404
    bad = client.get(
        "/api/alarm-fatigue?since=2026-01-02T00:00:00Z&until=2026-01-01T00:00:00Z",
        headers=nurse_b.headers,
    )
    assert bad.status_code == 422 and "until" in bad.json()["detail"]
    assert client.get("/api/alarm-history").status_code == 401


def test_replay_json_is_what_the_response_models_give(client, make_account, session_factory):
    """The replay is encoded without a model per frame: the same JSON as AlarmReplayOut of the
    frames decoded one by one (depth with unknown points, frames without depth)."""
    from backend.alarm_review.schemas import AlarmReplayOut, ReplayFrameOut
    from backend.alarms.schemas import AlarmOut
    from backend.models import Alarm, Frame
    from tests.backend.alarm_review.factories import alarm, robot_with_frames
    from vigil.skeleton import decode_keypoints, depth_to_json, encode_depth

    engineer = make_account(Role.ENGINEER, ward=None, username="eng")
    with transaction(session_factory) as session:
        video = robot_with_frames(session)
        depth = np.linspace(1, 3, 25).astype(np.float32)
        depth[4] = np.nan
        for row in session.scalars(select(Frame).where(Frame.index % 3 == 0)):
            row.depth = encode_depth(depth)
        alarm_id = alarm(session, video).id
    response = client.get(
        f"/api/alarms/{alarm_id}/replay?before_s=2&after_s=1", headers=engineer.headers
    )
    with session_factory() as session:
        row = session.get(Alarm, alarm_id)
        frames = session.scalars(
            select(Frame)
            .where(Frame.ts >= row.first_frame_ts - 2, Frame.ts <= row.last_frame_ts + 1)
            .order_by(Frame.ts)
        ).all()
        expected = AlarmReplayOut(
            alarm=AlarmOut.model_validate(row),
            before_s=2,
            after_s=1,
            generated=False,
            frames=[
                ReplayFrameOut(
                    seq=f.seq,
                    index=f.index,
                    ts=f.ts,
                    keypoints=decode_keypoints(f.keypoints).tolist(),
                    depth=depth_to_json(f.depth),
                    decision=f.decision,
                    scores=f.scores or {},
                    model_version=f.model_version,
                )
                for f in frames
            ],
        )
    assert response.status_code == 200
    assert response.headers["content-type"] == "application/json"
    assert len(frames) == 47 and any(f.depth is None for f in frames)
    assert response.json() == expected.model_dump(mode="json")
    assert AlarmReplayOut.model_validate_json(response.content) == expected
