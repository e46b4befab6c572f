"""The foundation slice in-process: robot websocket -> frames stored -> Emergency decision ->
alarm row -> pushed to a nurse's websocket -> acknowledged -> stored with who and when."""

from __future__ import annotations

import json
import time

from sqlalchemy import func, select

from backend.models import Alarm, AlarmEvent, AlarmState, Frame, Role
from tests.backend.conftest import ROBOT_TOKEN
from vigil.protocol import FrameBatch, FrameRecord, Hello, TransportStart


def frame(seq: int, decision: str = "normal", transport: str = "t-1") -> FrameRecord:
    keypoints = [[100.0 + i, 200.0 + i, 0.9] for i in range(25)]
    return FrameRecord(
        seq=seq,
        ts=time.time(),
        transport_id=transport,
        keypoints=keypoints,
        depth=[2.0] * 24 + [None],
        floor=[1.5, 0.75, None],
        decision=decision,
        scores={"normal": 0.1, "emergency": 0.9} if decision == "emergency" else {"normal": 0.9},
        model_version="m-1",
        threshold=0.4,
        delay_ms=120,
    )


def test_emergency_reaches_nurse_and_acknowledgement_is_stored(
    client, make_account, robot, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    other_ward_nurse = make_account(Role.NURSE, ward="ward-b", username="bob")

    with (
        client.websocket_connect("/ws/browser", headers=nurse.headers) as browser,
        client.websocket_connect("/ws/browser", headers=other_ward_nurse.headers) as other,
        client.websocket_connect("/ws/robot") as ws,
    ):
        assert browser.receive_json() == {"type": "snapshot", "alarms": []}
        assert other.receive_json() == {"type": "snapshot", "alarms": []}
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text()) == {
            "type": "welcome",
            "protocol": 1,
            "robot_id": robot,
            "last_seq": None,
        }
        start = TransportStart(
            transport_id="t-1", mode="walking", patient="P-17", location="corridor B", ts=0.0
        )
        ws.send_text(start.model_dump_json())
        batch = FrameBatch(frames=[frame(0), frame(1), frame(2, "emergency")])
        ws.send_text(batch.model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 2}

        pushed = browser.receive_json()
        assert pushed["type"] == "alarm"
        alarm = pushed["alarm"]
        assert (alarm["kind"], alarm["state"], alarm["priority"]) == ("emergency", "open", "high")
        assert (alarm["patient"], alarm["location"], alarm["first_seq"]) == (
            "P-17",
            "corridor B",
            2,
        )

        # Repeated emergency decisions update the one open alarm instead of piling up.
        ws.send_text(
            FrameBatch(frames=[frame(3, "emergency"), frame(4, "emergency")]).model_dump_json()
        )
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 4}
        updated = browser.receive_json()["alarm"]
        assert updated["id"] == alarm["id"] and updated["last_seq"] == 4

    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Frame)) == 5
        assert session.scalar(select(func.count()).select_from(Alarm)) == 1

    # The nurse of another ward neither saw it nor may acknowledge it.
    response = client.post(
        f"/api/alarms/{alarm['id']}/acknowledge", headers=other_ward_nurse.headers
    )
    assert response.status_code == 404

    response = client.post(f"/api/alarms/{alarm['id']}/acknowledge", headers=nurse.headers)
    assert response.status_code == 200, response.text
    assert response.json()["state"] == "acknowledged"
    assert response.json()["acknowledged_by"] == "alice"

    with session_factory() as session:
        stored = session.get(Alarm, alarm["id"])
        assert stored.state == AlarmState.ACKNOWLEDGED
        assert stored.acknowledged_by == "alice"
        assert stored.acknowledged_at is not None
        events = session.scalars(select(AlarmEvent).order_by(AlarmEvent.id)).all()
        assert [(e.action, e.from_state, e.to_state, e.actor) for e in events] == [
            ("raise", None, "open", "robot:robot-a"),
            ("acknowledge", "open", "acknowledged", "nurse:alice"),
        ]

    # Acknowledging twice is an illegal transition.
    again = client.post(f"/api/alarms/{alarm['id']}/acknowledge", headers=nurse.headers)
    assert again.status_code == 409
    assert "acknowledged" in again.json()["detail"]


def test_frames_sent_twice_are_stored_once(client, robot, session_factory):
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        ws.receive_text()
        for _ in range(2):
            ws.send_text(FrameBatch(frames=[frame(7), frame(8)]).model_dump_json())
            assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 8}
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text())["last_seq"] == 8
    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Frame)) == 2


def test_a_continuing_emergency_reaches_the_board_coalesced_and_ends_on_its_last_decision(
    client, make_account, robot
):
    """Each frame of a patient on the floor folds into the one alarm; the boards get that at
    most about once a second (not once per frame), and always the last decision."""
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    with (
        client.websocket_connect("/ws/browser", headers=nurse.headers) as browser,
        client.websocket_connect("/ws/robot") as ws,
    ):
        assert browser.receive_json()["type"] == "snapshot"
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        ws.receive_text()
        ws.send_text(TransportStart(transport_id="t-1", mode="walking", ts=0.0).model_dump_json())
        ws.send_text(FrameBatch(frames=[frame(0, "emergency")]).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 0}
        raised = browser.receive_json()["alarm"]
        assert raised["last_seq"] == 0
        for seq in range(1, 21):  # one message per frame, as a robot at 10 Hz sends them
            ws.send_text(FrameBatch(frames=[frame(seq, "emergency")]).model_dump_json())
            assert json.loads(ws.receive_text()) == {"type": "ack", "seq": seq}
        pushes = []
        while not pushes or pushes[-1]["last_seq"] != 20:
            pushed = browser.receive_json()["alarm"]
            if pushed["id"] == raised["id"]:
                pushes.append(pushed)
    assert len(pushes) < 10  # twenty folds, coalesced
    assert (pushes[-1]["decision_count"], pushes[-1]["state"]) == (21, "open")
