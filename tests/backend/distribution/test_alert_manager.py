"""IHE PCD ACM alarm distribution end to end: a robot's Emergency over the real robot websocket
becomes an ORU^R40 at a real MLLP Alert Manager; its ACK, its outage, and the dispositions it
reports back (ORA^R41) reach the alarm, its audit and the board."""

from __future__ import annotations

import asyncio

from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.distribution.hl7_messages import (
    Change,
    Disposition,
    build_alert_status,
    parse_ack,
)
from backend.main import create_app
from backend.models import AlarmMessage, MessageStatus
from tests.backend.distribution.conftest import stream_an_emergency, wait_for


def _emergency_reports(manager, change: Change | None = None):
    return [
        r
        for r in manager.received
        if r.kind == "emergency" and (change is None or r.change is change)
    ]


def _alarms(client: TestClient, nurse, kind: str) -> list[dict]:
    response = client.get("/api/alarms", params={"kind": kind}, headers=nurse.headers)
    assert response.status_code == 200, response.text
    return response.json()


def _messages(session_factory) -> list[AlarmMessage]:
    with session_factory() as session:
        return list(session.scalars(select(AlarmMessage).order_by(AlarmMessage.id)))


def test_an_emergency_and_its_acknowledgement_reach_the_alert_manager_as_oru_r40(
    distributing_client, make_alert_manager, nurse, robot, session_factory
):
    manager = make_alert_manager(deliver_after_s=None, read_after_s=None)

    stream_an_emergency(distributing_client, robot)

    raised = wait_for(lambda: _emergency_reports(manager, Change.RAISED), what="ORU^R40 raised")[0]
    assert raised.priority == "PH" and raised.ward == "ward-a"
    assert "Patient emergency" in raised.text and "P-17" in raised.text
    assert "corridor B" in raised.text and "robot robot-a" in raised.text
    [alarm] = _alarms(distributing_client, nurse, "emergency")
    assert raised.alarm_id == alarm["id"]

    response = distributing_client.post(
        f"/api/alarms/{alarm['id']}/acknowledge", headers=nurse.headers, json={}
    )
    assert response.status_code == 200, response.text
    acknowledged = wait_for(
        lambda: _emergency_reports(manager, Change.ACKNOWLEDGED), what="ORU^R40 acknowledged"
    )[0]
    assert "acknowledged by alice" in acknowledged.text

    messages = [m for m in _messages(session_factory) if m.alarm_id == alarm["id"]]
    assert [m.change for m in messages] == ["raised", "acknowledged"]
    wait_for(lambda: all(m.status == MessageStatus.DELIVERED for m in _messages(session_factory)))
    delivered = [m for m in _messages(session_factory) if m.alarm_id == alarm["id"]]
    assert [(m.ack_code, m.attempts) for m in delivered] == [("AA", 1), ("AA", 1)]
    # Each change reached the Alert Manager exactly once, in order.
    assert [r.change for r in _emergency_reports(manager)] == [Change.RAISED, Change.ACKNOWLEDGED]


def test_an_accept_on_the_phone_acknowledges_the_alarm_with_the_dispositions_on_the_board(
    distributing_client, make_alert_manager, nurse, robot, session_factory
):
    manager = make_alert_manager(deliver_after_s=0.05, read_after_s=0.1, accept_after_s=0.15)

    with distributing_client.websocket_connect("/ws/browser", headers=nurse.headers) as board:
        assert board.receive_json()["type"] == "snapshot"
        stream_an_emergency(distributing_client, robot)

        def acknowledged_on_board():
            pushed = board.receive_json()
            alarm = pushed.get("alarm") or {}
            return (
                alarm
                if alarm.get("kind") == "emergency" and alarm["state"] == "acknowledged"
                else None
            )

        seen = wait_for(acknowledged_on_board, what="the board shows the accept")
    assert seen["acknowledged_by"] == "Anna Berg on Anna's phone"
    assert [d["disposition"] for d in seen["dispositions"]] == ["delivered", "read", "accepted"]
    assert {(d["clinician"], d["device"]) for d in seen["dispositions"]} == {
        ("Anna Berg", "Anna's phone")
    }

    alarm = distributing_client.get(f"/api/alarms/{seen['id']}", headers=nurse.headers).json()
    assert alarm["state"] == "acknowledged" and len(alarm["dispositions"]) == 3
    events = distributing_client.get(
        f"/api/alarms/{seen['id']}/events", headers=nurse.headers
    ).json()
    comments = [(e["action"], e["actor"], e["comment"]) for e in events]
    assert any(
        action == "disposition" and comment.startswith("delivered to Anna's phone (Anna Berg)")
        for action, _, comment in comments
    ), comments
    assert ("acknowledge", "phone:Anna Berg on Anna's phone", "accepted on Anna's phone") in [
        c for c in comments if c[0] == "acknowledge"
    ]
    # Vigil answered every status with AA, and told the Alert Manager of the acknowledgement.
    wait_for(lambda: len(manager.simulator.status_answers) == 3)
    assert manager.simulator.status_answers == ["AA", "AA", "AA"]
    wait_for(lambda: _emergency_reports(manager, Change.ACKNOWLEDGED), what="acknowledged sent")


def test_a_status_vigil_cannot_place_is_answered_ae_naming_the_field(
    distributing_client, make_alert_manager, robot, session_factory
):
    manager = make_alert_manager(deliver_after_s=None, read_after_s=None)
    stream_an_emergency(distributing_client, robot)
    raised = wait_for(lambda: _emergency_reports(manager, Change.RAISED))[0]

    unknown = raised.__class__(**{**_fields(raised), "control_id": "NOT-SENT-BY-VIGIL"})
    code = manager.run(manager.simulator.send_status(unknown, Disposition.ACCEPTED))
    assert code == "AE"

    import hl7.mllp  # a status with a disposition Vigil does not know

    async def send_raw(text: str) -> tuple[str, str]:
        reader, writer = await hl7.mllp.open_hl7_connection(
            "127.0.0.1", manager.simulator.vigil.port
        )
        writer.writeblock(text.encode())
        await writer.drain()
        ack = parse_ack((await asyncio.wait_for(reader.readblock(), 5)).decode())
        writer.close()
        return ack.code, ack.text

    from datetime import UTC, datetime

    text = build_alert_status(
        raised.control_id,
        raised.alarm_id,
        Disposition.READ,
        "RN1",
        "Berg",
        "Anna",
        "P1",
        "Anna's phone",
        datetime.now(UTC),
    )
    code, reason = manager.run(send_raw(text.replace("|read|", "|forwarded|")))
    assert code == "AE" and "OBX-5" in reason and "forwarded" in reason
    with session_factory() as session:
        from backend.models import Alarm

        alarm = session.get(Alarm, raised.alarm_id)
        assert alarm.state == "open" and alarm.dispositions == []


def _fields(report) -> dict:
    return {name: getattr(report, name) for name in report.__slots__}


def test_an_unreachable_alert_manager_shows_distribution_down_and_loses_no_message(
    distribution_settings, make_alert_manager, nurse, robot, session_factory
):
    manager = make_alert_manager(start=False, deliver_after_s=None, read_after_s=None)
    with TestClient(create_app(distribution_settings)) as client:
        stream_an_emergency(client, robot)
        [down] = wait_for(
            lambda: _alarms(client, nurse, "alarm_distribution_down"), what="distribution down"
        )
        assert down["state"] == "open" and down["robot_id"] is None and down["ward"] == "ward-a"
        assert "Alert Manager 127.0.0.1" in down["details"]["summary"]
        assert down["details"]["pending_messages"] >= 1
        pending = [m for m in _messages(session_factory) if m.status == MessageStatus.PENDING]
        assert pending and all(m.attempts >= 1 for m in pending)

    # The backend restarts while the Alert Manager is still down (the queue is in the
    # database), and then the Alert Manager comes back.
    with TestClient(create_app(distribution_settings)) as client:
        manager.start()
        wait_for(lambda: _emergency_reports(manager, Change.RAISED), what="delivered after restart")
        wait_for(
            lambda: _alarms(client, nurse, "alarm_distribution_down")[0]["state"] == "resolved",
            what="distribution down cleared",
        )
        wait_for(
            lambda: all(m.status == MessageStatus.DELIVERED for m in _messages(session_factory))
        )
    messages = _messages(session_factory)
    received = [r.control_id for r in manager.received]
    assert sorted(received) == sorted(m.control_id for m in messages)  # none lost, none twice
    assert all(m.ack_code == "AA" for m in messages)
    # "Alarm distribution down" itself is never sent to the Alert Manager it is about.
    assert all(r.kind != "alarm_distribution_down" for r in manager.received)


def test_a_lost_ack_is_resent_with_the_same_control_id_and_counted_once(
    distributing_client, make_alert_manager, robot, session_factory
):
    manager = make_alert_manager(answer=None, deliver_after_s=None, read_after_s=None)
    stream_an_emergency(distributing_client, robot)
    first = wait_for(lambda: _emergency_reports(manager, Change.RAISED))[0]
    wait_for(lambda: _messages(session_factory)[0].attempts >= 2, what="a resend")
    manager.simulator.answer = "AA"
    wait_for(lambda: _messages(session_factory)[0].status == MessageStatus.DELIVERED)
    message = _messages(session_factory)[0]
    assert message.control_id == first.control_id and message.attempts >= 3
    # The Alert Manager saw repeats of one message, not new alerts.
    assert [r.control_id for r in _emergency_reports(manager, Change.RAISED)] == [first.control_id]
    assert manager.simulator.arrivals.count(first.control_id) >= 3


def test_a_message_that_cannot_be_built_is_refused_with_its_reason_and_the_alarm_stays(
    distributing_client, make_alert_manager, monkeypatch, nurse, robot, session_factory
):
    """The ORU^R40 is built by the sender, after the change is stored: a message that fails
    to build or validate never takes the Emergency down with it (and building, tens of
    milliseconds, never holds the frame writer's transaction)."""
    from backend.distribution import sender as sender_module
    from backend.distribution.hl7_messages import MessageError

    def unbuildable(report, facility):
        raise MessageError("ORU^R40 does not validate against HL7 v2.6")

    monkeypatch.setattr(sender_module, "build_alert_report", unbuildable)
    manager = make_alert_manager(deliver_after_s=None, read_after_s=None)

    stream_an_emergency(distributing_client, robot)

    [alarm] = wait_for(lambda: _alarms(distributing_client, nurse, "emergency"))
    wait_for(lambda: [m for m in _messages(session_factory) if m.status != MessageStatus.PENDING])
    [message] = [m for m in _messages(session_factory) if m.alarm_id == alarm["id"]]
    assert message.status == MessageStatus.REFUSED and message.payload is None
    assert "not a valid HL7 v2.6 ORU^R40" in message.last_error
    assert message.report is not None and f'"alarm_id":{alarm["id"]}' in message.report
    assert _emergency_reports(manager) == []
