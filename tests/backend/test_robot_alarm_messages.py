"""Backend -> robot alarm messages (issue #33): a nurse's acknowledge sends the robot
`alarm_acknowledged` (who, when), a resolve sends `alarm_resolved` (releases its emergency stop),
both after the commit; a reset made on the robot (`emergency_reset`) lands in the alarm's audit;
what the robot does (`behaviour_changed`) is on the alarm, in its audit and on the fleet page."""

from __future__ import annotations

import json
import time

import pytest
from sqlalchemy import select

from backend.models import AlarmEvent, Role
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from vigil.protocol import (
    BehaviourChanged,
    EmergencyReset,
    FrameBatch,
    Hello,
    TransportStart,
    server_message_adapter,
)


def _robot_with_an_emergency(ws, robot: str) -> None:
    ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
    assert json.loads(ws.receive_text())["type"] == "welcome"
    start = TransportStart(transport_id="t-1", mode="walking", patient="P-1", ts=0.0)
    ws.send_text(start.model_dump_json())
    ws.send_text(FrameBatch(frames=[frame(0), frame(1, "emergency")]).model_dump_json())
    assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 1}


# A message that never comes would block receive_text: fail instead of hanging.
@pytest.mark.timeout(30)
def test_acknowledge_and_resolve_are_sent_to_the_robot(client, make_account, robot):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    with client.websocket_connect("/ws/robot") as ws:
        _robot_with_an_emergency(ws, robot)
        (alarm,) = client.get("/api/alarms", headers=nurse.headers).json()
        before = time.time()
        response = client.post(f"/api/alarms/{alarm['id']}/acknowledge", headers=nurse.headers)
        assert response.status_code == 200, response.text
        told = server_message_adapter.validate_json(ws.receive_text())
        assert told.type == "alarm_acknowledged"
        assert (told.alarm_id, told.kind, told.transport_id) == (alarm["id"], "emergency", "t-1")
        assert told.by == "nurse:alice" and told.at >= before - 1

        response = client.post(
            f"/api/alarms/{alarm['id']}/resolve",
            headers=nurse.headers,
            json={"verdict": "true_emergency"},
        )
        assert response.status_code == 200, response.text
        told = server_message_adapter.validate_json(ws.receive_text())
        assert told.type == "alarm_resolved"
        assert (told.alarm_id, told.by, told.verdict) == (
            alarm["id"],
            "nurse:alice",
            "true_emergency",
        )


def test_a_reset_on_the_robot_is_audited_on_its_alarm(client, make_account, robot, session_factory):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    with client.websocket_connect("/ws/robot") as ws:
        _robot_with_an_emergency(ws, robot)
        (alarm,) = client.get("/api/alarms", headers=nurse.headers).json()
        reset = EmergencyReset(ts=time.time(), transport_id="t-1", by="cli")
        ws.send_text(reset.model_dump_json())
        # the writer stores in order: a frame after it is acked once the reset is stored
        ws.send_text(FrameBatch(frames=[frame(2)]).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 2}
    with session_factory() as session:
        events = session.scalars(
            select(AlarmEvent).where(AlarmEvent.alarm_id == alarm["id"]).order_by(AlarmEvent.id)
        ).all()
        last = events[-1]
        assert (last.action, last.from_state, last.to_state) == ("robot_reset", "open", "open")
        assert last.actor == "robot:robot-a" and "reset on the robot (cli)" in last.comment
    assert client.get(f"/api/alarms/{alarm['id']}", headers=nurse.headers).json()["state"] == "open"


def test_what_the_robot_did_is_on_its_alarm_its_audit_and_the_fleet(
    client, make_account, robot, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    engineer = make_account(Role.ENGINEER, username="eve")
    fleet = client.get("/api/fleet", headers=engineer.headers).json()
    assert [r["behaviour_state"] for r in fleet if r["id"] == robot] == [None]
    stopped_at = time.time()
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        browser.receive_json()  # the snapshot
        with client.websocket_connect("/ws/robot") as ws:
            _robot_with_an_emergency(ws, robot)
            first = browser.receive_json()["alarm"]
            assert first["robot_state"] is None
            stop = BehaviourChanged(
                ts=stopped_at,
                state="emergency_stop",
                since=stopped_at,
                transport_id="t-1",
                reason="Emergency decision: stop, call for help",
            )
            ws.send_text(stop.model_dump_json())
            ws.send_text(FrameBatch(frames=[frame(2)]).model_dump_json())
            assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 2}
            pushed = browser.receive_json()["alarm"]
    assert pushed["id"] == first["id"] and pushed["state"] == "open"
    assert pushed["robot_state"] == "emergency_stop"
    assert abs(_ts(pushed["robot_state_since"]) - stopped_at) < 1e-3
    read = client.get(f"/api/alarms/{first['id']}", headers=nurse.headers).json()
    assert (read["robot_state"], read["robot_state_since"]) == (
        "emergency_stop",
        pushed["robot_state_since"],
    )
    with session_factory() as session:
        last = session.scalars(
            select(AlarmEvent).where(AlarmEvent.alarm_id == first["id"]).order_by(AlarmEvent.id)
        ).all()[-1]
    assert (last.action, last.from_state, last.to_state) == ("robot_behaviour", "open", "open")
    assert last.actor == "robot:robot-a"
    assert last.comment.startswith("robot stopped, waiting for help (emergency_stop) at ")
    (row,) = [
        r for r in client.get("/api/fleet", headers=engineer.headers).json() if r["id"] == robot
    ]
    assert row["behaviour_state"] == "emergency_stop"
    assert row["behaviour_reason"] == "Emergency decision: stop, call for help"
    assert abs(_ts(row["behaviour_since"]) - stopped_at) < 1e-3


def test_a_behaviour_change_with_an_unknown_state_is_refused_with_a_reason(client, robot):
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text())["type"] == "welcome"
        ws.send_text(
            json.dumps(
                {
                    "type": "behaviour_changed",
                    "ts": 1.0,
                    "since": 1.0,
                    "state": "dancing",
                }
            )
        )
        message = ws.receive()
    assert message["type"] == "websocket.close" and message["code"] == 4400
    assert "state" in message["reason"]


def _ts(iso: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(iso.replace("Z", "+00:00")).timestamp()
