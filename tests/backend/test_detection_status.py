"""What a robot can feed and how its detection is doing: hello inputs stored and shown, the
detection_status message raising and clearing the technical alarm "detection degraded" in stream
order with the frames, and the transport's real frame rate on its recording."""

from __future__ import annotations

import json

from sqlalchemy import select

from backend.models import Alarm, AlarmEvent, Role, Video
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from vigil.protocol import DetectionStatus, FrameBatch, Hello, TransportStart


def connect(ws, robot: str, **hello) -> dict:
    ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN, **hello).model_dump_json())
    return json.loads(ws.receive_text())


def commit(ws, *frames) -> None:
    """Frames after the messages sent before them: their ack means those are committed too."""
    ws.send_text(FrameBatch(frames=list(frames)).model_dump_json())
    assert json.loads(ws.receive_text()) == {"type": "ack", "seq": frames[-1].seq}


def degraded(ts: float, degraded: bool = True, **fields) -> str:
    values = {
        "transport_id": "t-1",
        "missing_inputs": ["floor"] if degraded else [],
        "assigned_model": "gbt-floor-1",
        "running_model": "gbt-kp-1" if degraded else "gbt-floor-1",
        "reason": "no camera mount" if degraded else "camera mount restored",
    } | fields
    return DetectionStatus(ts=ts, degraded=degraded, **values).model_dump_json()


def test_hello_inputs_are_stored_and_an_older_agent_feeds_keypoints_only(
    client, robot, make_account
):
    engineer = make_account(Role.ENGINEER)
    with client.websocket_connect("/ws/robot") as ws:
        assert connect(ws, robot, inputs=["depth", "keypoints"])["type"] == "welcome"
        commit(ws, frame(0))
    shown = client.get(f"/api/robots/{robot}", headers=engineer.headers).json()
    assert (shown["inputs"], shown["inputs_reported"]) == (["keypoints", "depth"], True)
    fleet = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}
    assert fleet[robot]["inputs"] == ["keypoints", "depth"]

    with client.websocket_connect("/ws/robot") as ws:  # an agent that predates hello.inputs
        connect(ws, robot)
        commit(ws, frame(1))
    shown = client.get("/api/robots", headers=engineer.headers).json()[0]
    assert (shown["inputs"], shown["inputs_reported"]) == (["keypoints"], False)


def test_detection_degraded_is_raised_in_stream_order_and_cleared_on_recovery(
    client, robot, make_account, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a")
    with (
        client.websocket_connect("/ws/browser", headers=nurse.headers) as browser,
        client.websocket_connect("/ws/robot") as ws,
    ):
        assert browser.receive_json()["alarms"] == []
        connect(ws, robot, inputs=["keypoints", "depth"])
        ws.send_text(
            TransportStart(
                transport_id="t-1", mode="walking", patient="P-4", location="lift 2", ts=0.0
            ).model_dump_json()
        )
        # Frames 0-2, then the status, then frame 3, all in one flush: the alarm is placed
        # after frame 2, where the robot's stream put it.
        ws.send_text(FrameBatch(frames=[frame(0), frame(1), frame(2)]).model_dump_json())
        ws.send_text(degraded(100.0))
        commit(ws, frame(3))

        pushed = browser.receive_json()["alarm"]
        assert (pushed["kind"], pushed["priority"], pushed["state"]) == (
            "detection_degraded",
            "technical",
            "open",
        )
        assert (pushed["transport_id"], pushed["patient"], pushed["location"]) == (
            "t-1",
            "P-4",
            "lift 2",
        )
        assert (pushed["first_seq"], pushed["model_version"]) == (2, "gbt-kp-1")
        details = pushed["details"]
        assert details["missing_inputs"] == ["floor"] and details["reason"] == "no camera mount"
        assert details["summary"] == "no floor measures, running keypoints-only fallback gbt-kp-1"
        assert details["fallback"] is True

        listed = client.get(
            "/api/alarms", params={"kind": "detection_degraded"}, headers=nurse.headers
        ).json()
        assert [a["id"] for a in listed] == [pushed["id"]]

        # Still degraded (a later status): the same alarm, updated; a replay changes nothing.
        ws.send_text(degraded(101.0, missing_inputs=["depth", "floor"]))
        ws.send_text(degraded(101.0))
        commit(ws, frame(4))
        again = browser.receive_json()["alarm"]
        assert again["id"] == pushed["id"] and again["decision_count"] == 2
        assert again["details"]["missing_inputs"] == ["depth", "floor"]

        # Recovered: cleared as the cause ended, and the board drops it.
        ws.send_text(degraded(102.0, degraded=False))
        commit(ws, frame(5))
        cleared = browser.receive_json()["alarm"]
        assert (cleared["id"], cleared["state"], cleared["verdict"]) == (
            pushed["id"],
            "resolved",
            None,
        )
        # A replay of the first status (resent from the outbox after a reconnect) is older
        # than what the alarm last saw: it raises nothing.
        ws.send_text(degraded(100.0))
        commit(ws, frame(6))
        ws.send_text(degraded(103.0, reason="depth stream stopped"))
        commit(ws, frame(7))
        second = browser.receive_json()["alarm"]
        assert second["id"] != pushed["id"] and second["state"] == "open"
        assert second["first_seq"] == 6

    with session_factory() as session:
        alarms = session.scalars(select(Alarm).order_by(Alarm.id)).all()
        assert [(a.kind, a.state) for a in alarms] == [
            ("detection_degraded", "resolved"),
            ("detection_degraded", "open"),
        ]
        trail = session.scalars(
            select(AlarmEvent).where(AlarmEvent.alarm_id == pushed["id"]).order_by(AlarmEvent.id)
        ).all()
        assert [(e.action, e.from_state, e.to_state, e.actor) for e in trail] == [
            ("raise", None, "open", "system"),
            ("clear", "open", "resolved", "system"),
        ]
        assert "detection recovered" in trail[-1].comment


def test_a_status_naming_another_robots_transport_closes_the_connection(
    client, robot, session_factory
):
    from backend.db import transaction
    from backend.models import Robot
    from backend.security import hash_robot_token

    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b", ward="ward-a", token_hash=hash_robot_token("tok-b")))
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id="robot-b", token="tok-b").model_dump_json())
        ws.receive_text()
        ws.send_text(TransportStart(transport_id="t-b", mode="walking", ts=0.0).model_dump_json())
        ws.send_text(FrameBatch(frames=[frame(0, transport="t-b")]).model_dump_json())
        ws.receive_text()
    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot)
        ws.send_text(degraded(1.0, transport_id="t-b"))
        closed = ws.receive()
        assert closed["type"] == "websocket.close" and closed["code"] == 4403  # CLOSE_FORBIDDEN
        assert "belongs to another robot" in closed["reason"]


def test_the_transports_real_frame_rate_is_stored_on_its_recording(
    client, robot, make_account, session_factory
):
    annotator = make_account(Role.ANNOTATOR)
    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot)
        ws.send_text(
            TransportStart(transport_id="t-1", mode="walking", ts=0.0, fps=23.976).model_dump_json()
        )
        ws.send_text(TransportStart(transport_id="t-2", mode="walking", ts=9.0).model_dump_json())
        commit(ws, frame(0, transport="t-1"), frame(1, transport="t-2"))
    with session_factory() as session:
        videos = {v.transport_id: v.id for v in session.scalars(select(Video))}
    fps = {
        t: client.get(f"/api/videos/{v}", headers=annotator.headers).json()["fps"]
        for t, v in videos.items()
    }
    assert fps == {"t-1": 23.976, "t-2": 30.0}
