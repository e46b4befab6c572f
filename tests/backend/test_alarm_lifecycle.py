"""Alarm lifecycle beyond the first alarm: escalation per ward, re-alarm, technical alarms from
the monitor, resolve verdicts, illegal transitions (409) and the audit trail."""

from __future__ import annotations

import json
import uuid
from datetime import timedelta

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.db import transaction
from backend.ingest.waiting import SharedWaiting
from backend.main import create_app
from backend.models import Alarm, AlarmEvent, AlarmKind, AlarmState, Robot, Role
from backend.models._types import utcnow
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from tests.backend.test_reliability import REDIS_URL
from vigil.protocol import FrameBatch, Heartbeat, Hello, TransportEnd, TransportStart


@pytest.fixture
def settings(settings):
    settings.monitor_interval_s = 3600  # the tests run the monitor passes themselves
    settings.escalation_seconds = 60
    settings.escalation_seconds_by_ward = {"ward-a": 30}
    settings.escalation_max_level = 2
    settings.realarm_minutes = 10
    settings.missed_escalation_seconds = 120
    settings.missed_escalation_chain = ["charge nurse", "rapid-response team"]
    settings.missed_escalation_chain_by_ward = {"ward-b": ["charge nurse B"]}
    settings.stream_stall_seconds = 5
    settings.robot_offline_seconds = 10
    return settings


def stream(client, robot_id: str, token: str, transport: str, *frames, end: bool = True) -> None:
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot_id, token=token).model_dump_json())
        ws.receive_text()
        ws.send_text(
            TransportStart(
                transport_id=transport, mode="walking", patient="P-1", ts=0.0
            ).model_dump_json()
        )
        ws.send_text(FrameBatch(frames=list(frames)).model_dump_json())
        assert json.loads(ws.receive_text())["type"] == "ack"
        if end:
            ws.send_text(TransportEnd(transport_id=transport, ts=1.0).model_dump_json())
            ws.send_text(Heartbeat(ts=1.0).model_dump_json())
            ws.send_text(FrameBatch(frames=[frames[-1]]).model_dump_json())  # a replay
            assert json.loads(ws.receive_text())["type"] == "ack"  # so the end is committed


def tick(client, now) -> list[dict]:
    return client.portal.call(client.app.state.services.monitor.tick, now)


def events(session_factory, alarm_id: int) -> list[tuple[str, str | None, str, str]]:
    with session_factory() as session:
        rows = session.scalars(
            select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
        )
        return [(e.action, e.from_state, e.to_state, e.actor) for e in rows]


def test_unacknowledged_emergency_escalates_per_ward_and_is_pushed_again(
    client, robot, make_account, session_factory
):
    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b", ward="ward-b", token_hash=hash_robot_token("tok-b")))
    nurse = make_account(Role.NURSE, ward="ward-a")
    stream(client, robot, ROBOT_TOKEN, "t-a", frame(0, "emergency", "t-a"))
    stream(client, "robot-b", "tok-b", "t-b", frame(0, "emergency", "t-b"))
    with session_factory() as session:
        alarm_a, alarm_b = session.scalars(select(Alarm).order_by(Alarm.robot_id)).all()
    start = alarm_a.raised_at

    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        snapshot = browser.receive_json()
        assert [a["id"] for a in snapshot["alarms"]] == [alarm_a.id]  # ward-a only

        assert tick(client, start + timedelta(seconds=29)) == []
        changed = tick(client, start + timedelta(seconds=31))
        # ward-a escalates after its own 30 s; ward-b waits for the default 60 s.
        assert [(a["id"], a["escalation_level"]) for a in changed] == [(alarm_a.id, 1)]
        pushed = browser.receive_json()
        assert pushed["alarm"]["id"] == alarm_a.id and pushed["alarm"]["escalation_level"] == 1

        changed = tick(client, start + timedelta(seconds=62))
        assert sorted((a["robot_id"], a["escalation_level"]) for a in changed) == [
            ("robot-a", 2),
            ("robot-b", 1),
        ]
        # The maximum level (2 here) is not exceeded: one more escalation time after it, the
        # alarm is "missed: needs review".
        changed = tick(client, start + timedelta(seconds=200))
        assert sorted((a["robot_id"], a["escalation_level"], a["state"]) for a in changed) == [
            ("robot-a", 2, "missed"),
            ("robot-b", 2, "open"),
        ]
        # Latched: the missed alarm stays missed and goes on to the ward's further responders
        # (120 s each here); robot-b's is missed after its 60 s.
        changed = tick(client, start + timedelta(seconds=400))
        assert sorted((a["robot_id"], a["state"], a["escalated_to"]) for a in changed) == [
            ("robot-a", "missed", "charge nurse"),
            ("robot-b", "missed", None),
        ]
        changed = tick(client, start + timedelta(seconds=4000))
        assert sorted((a["robot_id"], a["state"], a["escalated_to"]) for a in changed) == [
            ("robot-a", "missed", "rapid-response team"),
            ("robot-b", "missed", "charge nurse B"),
        ]
        assert tick(client, start + timedelta(seconds=8000)) == []  # the chains ended

    assert events(session_factory, alarm_a.id) == [
        ("raise", None, "open", "robot:robot-a"),
        ("escalate", "open", "open", "system"),
        ("escalate", "open", "open", "system"),
        ("miss", "open", "missed", "system"),
        ("escalate", "missed", "missed", "system"),
        ("escalate", "missed", "missed", "system"),
    ]
    # Each escalation says to whom: who had a board of the alarm's ward open at the time.
    with session_factory() as session:
        comments = {
            (e.alarm_id, e.comment)
            for e in session.scalars(select(AlarmEvent).where(AlarmEvent.action == "escalate"))
        }
    assert (
        alarm_a.id,
        "not acknowledged: escalated to level 1; announced again on every board "
        "showing ward ward-a (signed in: nurse-ward-a (nurse))",
    ) in comments
    assert (
        alarm_b.id,
        "not acknowledged: escalated to level 1; announced again on every board "
        "showing ward ward-b (nobody had a board of this ward open)",
    ) in comments


def test_acknowledged_alarm_not_resolved_in_time_realarms(
    client, robot, make_account, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "pause", "t-1"))
    with session_factory() as session:
        alarm = session.scalars(select(Alarm)).one()
    assert (alarm.kind, alarm.priority) == (AlarmKind.PAUSE, "medium")
    response = client.post(
        f"/api/alarms/{alarm.id}/acknowledge", headers=nurse.headers, json={"comment": "on my way"}
    )
    assert response.status_code == 200, response.text
    acknowledged_at = utcnow()

    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        browser.receive_json()
        assert tick(client, acknowledged_at + timedelta(minutes=9)) == []
        changed = tick(client, acknowledged_at + timedelta(minutes=10, seconds=1))
        assert [a["id"] for a in changed] == [alarm.id]
        assert changed[0]["state"] == "acknowledged" and changed[0]["realarmed_at"] is not None
        assert browser.receive_json()["alarm"]["realarmed_at"] is not None
        # Not again before another full period.
        assert tick(client, acknowledged_at + timedelta(minutes=15)) == []

    assert [e[0] for e in events(session_factory, alarm.id)] == ["raise", "acknowledge", "realarm"]


def test_stalled_stream_then_offline_robot_raise_one_technical_alarm_each(
    client, robot, session_factory
):
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "normal", "t-1"), end=False)
    now = utcnow()
    assert tick(client, now + timedelta(seconds=3)) == []
    stalled = tick(client, now + timedelta(seconds=6))
    assert [(a["kind"], a["priority"], a["transport_id"]) for a in stalled] == [
        ("stream_stalled", "technical", "t-1")
    ]
    assert tick(client, now + timedelta(seconds=7)) == []  # one alarm per outage
    offline = tick(client, now + timedelta(seconds=11))
    assert [a["kind"] for a in offline] == ["robot_offline"]
    assert tick(client, now + timedelta(seconds=30)) == []

    # A transport that ended raises nothing.
    with transaction(session_factory) as session:
        for transport in session.scalars(select(Alarm)):
            session.delete(transport)
        from backend.models import Transport

        session.get(Transport, "t-1").ended_at = now
    assert tick(client, now + timedelta(seconds=60)) == []


def clears(session_factory, alarm_id: int) -> list[tuple[str | None, str, str | None]]:
    with session_factory() as session:
        rows = session.scalars(
            select(AlarmEvent)
            .where(AlarmEvent.alarm_id == alarm_id, AlarmEvent.action == "clear")
            .order_by(AlarmEvent.id)
        )
        return [(e.from_state, e.to_state, e.comment) for e in rows]


def test_technical_alarms_clear_themselves_when_their_cause_ends(
    client, robot, make_account, session_factory
):
    """robot_offline and stream_stalled are not latching: the monitor resolves them (transition
    `clear`, actor system, no verdict) once the robot talks again, frames flow again or the
    transport ended; an acknowledged one too. They stay in the history and the handover."""
    nurse = make_account(Role.NURSE, ward="ward-a", username="olga")
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "normal", "t-1"), end=False)
    now = utcnow()
    (stalled,) = tick(client, now + timedelta(seconds=6))
    (offline,) = tick(client, now + timedelta(seconds=11))
    assert (stalled["kind"], offline["kind"]) == ("stream_stalled", "robot_offline")
    # Still silent: nothing clears, however often the monitor looks.
    assert tick(client, now + timedelta(seconds=20)) == []
    response = client.post(f"/api/alarms/{offline['id']}/acknowledge", headers=nurse.headers)
    assert response.status_code == 200, response.text

    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        browser.receive_json()  # the snapshot
        # The robot talks again (hello, heartbeat) but sends no frame: offline clears, the
        # stream is still stalled.
        with client.websocket_connect("/ws/robot") as ws:
            ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
            ws.receive_text()
            ws.send_text(Heartbeat(ts=2.0).model_dump_json())
            ws.send_text(FrameBatch(frames=[frame(0, "normal", "t-1")]).model_dump_json())  # replay
            assert json.loads(ws.receive_text())["type"] == "ack"
        changed = tick(client, utcnow())
        assert [(a["id"], a["state"]) for a in changed] == [(offline["id"], "resolved")]
        assert browser.receive_json()["alarm"]["state"] == "resolved"
        assert clears(session_factory, offline["id"]) == [
            ("acknowledged", "resolved", "cleared: robot talking again")
        ]
        # Frames flow again: the stalled stream clears.
        stream(client, robot, ROBOT_TOKEN, "t-1", frame(1, "normal", "t-1"), end=False)
        changed = tick(client, utcnow())
        assert [(a["id"], a["state"]) for a in changed] == [(stalled["id"], "resolved")]
        assert clears(session_factory, stalled["id"]) == [
            ("open", "resolved", "cleared: frames flowing again")
        ]
    assert tick(client, utcnow()) == []  # cleared once

    # A new outage raises a new alarm; the transport's normal end clears it.
    later = utcnow() + timedelta(seconds=6)
    (again,) = tick(client, later)
    assert again["kind"] == "stream_stalled" and again["id"] not in (stalled["id"], offline["id"])
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        ws.receive_text()
        ws.send_text(TransportEnd(transport_id="t-1", ts=3.0).model_dump_json())
        ws.send_text(FrameBatch(frames=[frame(1, "normal", "t-1")]).model_dump_json())  # replay
        assert json.loads(ws.receive_text())["type"] == "ack"
    changed = tick(client, later)
    assert [(a["id"], a["state"]) for a in changed] == [(again["id"], "resolved")]
    assert clears(session_factory, again["id"]) == [
        ("open", "resolved", "cleared: transport ended")
    ]
    for alarm_id in (stalled["id"], offline["id"], again["id"]):
        actions = [e[0] for e in events(session_factory, alarm_id)]
        assert actions[0] == "raise" and actions[-1] == "clear"
        with session_factory() as session:
            alarm = session.get(Alarm, alarm_id)
            assert alarm.verdict is None and alarm.resolved_by_id is None

    # The nurse still finds them: the history and the shift handover list them, resolved.
    history = client.get("/api/alarms", params={"state": "resolved"}, headers=nurse.headers)
    assert history.status_code == 200, history.text
    assert {a["id"] for a in history.json()} == {stalled["id"], offline["id"], again["id"]}
    handover = client.get("/api/handover", headers=nurse.headers).json()
    rows = {(r["section"], r["alarm"]["id"]) for r in handover["alarms"]}
    assert rows == {
        ("resolved", stalled["id"]),
        ("resolved", offline["id"]),
        ("resolved", again["id"]),
    }
    assert handover["fatigue"]["technical"] == 3


def test_resolve_verdicts_illegal_transitions_and_audit(
    client, robot, make_account, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="alice")
    engineer = make_account(Role.ENGINEER, ward=None, username="erin")
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "emergency", "t-1"))
    with session_factory() as session:
        alarm_id = session.scalars(select(Alarm.id)).one()
    url = f"/api/alarms/{alarm_id}"

    # A false alarm needs a reason; a true emergency must not have one.
    bad = client.post(f"{url}/resolve", headers=nurse.headers, json={"verdict": "false_alarm"})
    assert bad.status_code == 422 and "reason" in bad.text
    bad = client.post(
        f"{url}/resolve",
        headers=nurse.headers,
        json={"verdict": "true_emergency", "reason": "bending"},
    )
    assert bad.status_code == 422
    # Engineers see alarms but do not handle them.
    assert client.post(f"{url}/acknowledge", headers=engineer.headers).status_code == 403

    resolved = client.post(
        f"{url}/resolve",
        headers=nurse.headers,
        json={"verdict": "false_alarm", "reason": "bending", "comment": "picked up a glove"},
    )
    assert resolved.status_code == 200, resolved.text
    body = resolved.json()
    assert (body["state"], body["verdict"], body["reason"], body["resolved_by"]) == (
        "resolved",
        "false_alarm",
        "bending",
        "alice",
    )
    again = client.post(f"{url}/acknowledge", headers=nurse.headers)
    assert again.status_code == 409 and "resolved" in again.json()["detail"]
    assert (
        client.post(f"{url}/resolve", headers=nurse.headers, json={"verdict": "unsure"}).status_code
        == 409
    )

    # Filters.
    listed = client.get(
        "/api/alarms", params={"state": "resolved", "kind": "emergency"}, headers=nurse.headers
    ).json()
    assert [a["id"] for a in listed] == [alarm_id]
    assert client.get("/api/alarms", params={"state": "open"}, headers=nurse.headers).json() == []

    audit = client.get("/api/audit", params={"alarm_id": alarm_id}, headers=engineer.headers)
    assert audit.status_code == 200
    trail = [(e["action"], e["from_state"], e["to_state"], e["actor"]) for e in audit.json()]
    assert trail == [
        ("resolve", "open", "resolved", "nurse:alice"),
        ("raise", None, "open", "robot:robot-a"),
    ]
    assert "picked up a glove" in audit.json()[0]["comment"]

    # After resolution a new Emergency in the same transport opens a new alarm.
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(1, "emergency", "t-1"))
    with session_factory() as session:
        states = session.scalars(select(Alarm.state).order_by(Alarm.id)).all()
    assert states == [AlarmState.RESOLVED, AlarmState.OPEN]


def test_reconnecting_browser_first_receives_every_open_alarm(client, robot, make_account):
    nurse = make_account(Role.NURSE, ward="ward-a")
    stream(
        client, robot, ROBOT_TOKEN, "t-1", frame(0, "emergency", "t-1"), frame(1, "pause", "t-1")
    )
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        snapshot = browser.receive_json()
    assert snapshot["type"] == "snapshot"
    assert sorted(a["kind"] for a in snapshot["alarms"]) == ["emergency", "pause"]


def test_snapshot_holds_each_alarm_as_the_api_shows_it(client, robot, make_account):
    """The board's snapshot is one query of columns (alarms.queries.unresolved_rows): each alarm
    in it is what GET /api/alarms/{id} gives, who acknowledged it and its transport's end too."""
    nurse = make_account(Role.NURSE, ward="ward-a", username="nell")
    stream(
        client, robot, ROBOT_TOKEN, "t-1", frame(0, "emergency", "t-1"), frame(1, "pause", "t-1")
    )
    alarms = client.get("/api/alarms", headers=nurse.headers).json()
    emergency = next(a for a in alarms if a["kind"] == "emergency")
    acknowledged = client.post(f"/api/alarms/{emergency['id']}/acknowledge", headers=nurse.headers)
    assert acknowledged.status_code == 200, acknowledged.text
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        snapshot = browser.receive_json()["alarms"]
    assert [a["raised_at"] for a in snapshot] == sorted(a["raised_at"] for a in snapshot)
    by_id = {a["id"]: a for a in snapshot}
    assert len(by_id) == len(snapshot) == 2
    for alarm_id, pushed in by_id.items():
        assert pushed == client.get(f"/api/alarms/{alarm_id}", headers=nurse.headers).json()
    assert by_id[emergency["id"]]["acknowledged_by"] == "nell"
    assert all(a["transport_ended_at"] is not None for a in snapshot)


def test_missed_emergency_is_latched_says_its_transport_ended_and_counts_in_the_handover(
    client, robot, make_account, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a", username="nora")
    stream(client, robot, ROBOT_TOKEN, "t-m", frame(0, "emergency", "t-m"), end=False)
    with session_factory() as session:
        alarm = session.scalars(select(Alarm)).one()
    start = alarm.raised_at
    for seconds in (31, 62):
        tick(client, start + timedelta(seconds=seconds))
    changed = tick(client, start + timedelta(seconds=93))
    assert [(a["id"], a["state"]) for a in changed] == [(alarm.id, "missed")]

    # New decisions of the same transport fold into the missed alarm; the transport's end is
    # pushed to the board and leaves the latch alone.
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as browser:
        # (the silent robot's technical alarm is there too: not the subject here)
        snapshot = [a for a in browser.receive_json()["alarms"] if a["kind"] == "emergency"]
        assert [(a["id"], a["state"]) for a in snapshot] == [(alarm.id, "missed")]
        assert snapshot[0]["transport_ended_at"] is None
        with client.websocket_connect("/ws/robot") as ws:
            ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
            ws.receive_text()
            later = frame(1, "emergency", "t-m")
            ws.send_text(FrameBatch(frames=[later]).model_dump_json())
            assert json.loads(ws.receive_text())["type"] == "ack"
            ws.send_text(TransportEnd(transport_id="t-m", ts=2.0).model_dump_json())
            ws.send_text(FrameBatch(frames=[later]).model_dump_json())  # sent again
            assert json.loads(ws.receive_text())["type"] == "ack"
        pushed = [browser.receive_json()["alarm"] for _ in range(3)]
        pushed = [a for a in pushed if a["id"] == alarm.id]
        assert {(a["id"], a["state"]) for a in pushed} == {(alarm.id, "missed")}
        assert pushed[-1]["transport_ended_at"] is not None
        assert pushed[-1]["decision_count"] == 2
    # Still missed two hours on: it went on to the ward's further responders, and stays missed.
    later = [a for a in tick(client, start + timedelta(hours=2)) if a["id"] == alarm.id]
    assert [(a["state"], a["escalated_to"]) for a in later] == [("missed", "charge nurse")]

    handover = client.get("/api/handover", headers=nurse.headers)
    assert handover.status_code == 200, handover.text
    body = handover.json()
    assert body["counts"]["missed"] == 1 and body["counts"]["escalated"] == 1
    # The robot_offline alarm of the silent robot cleared itself once the robot talked again
    # and the transport ended; the missed Emergency stays latched.
    assert body["per_robot"] == [
        {
            "robot_id": robot,
            "alarms": 2,
            "open": 0,
            "missed": 1,
            "acknowledged_unresolved": 0,
            "resolved": 1,
            "escalated": 1,
            "ever_missed": 1,
        }
    ]
    rows = [(r["section"], r["alarm"]["id"]) for r in body["alarms"]]
    assert ("missed", alarm.id) in rows and len(rows) == 2

    # A nurse opens it: acknowledged (late), then resolved; the handover still counts it missed.
    response = client.post(f"/api/alarms/{alarm.id}/acknowledge", headers=nurse.headers)
    assert response.status_code == 200, response.text
    assert response.json()["state"] == "acknowledged"
    response = client.post(
        f"/api/alarms/{alarm.id}/resolve", headers=nurse.headers, json={"verdict": "true_emergency"}
    )
    assert response.status_code == 200, response.text
    body = client.get("/api/handover", headers=nurse.headers).json()
    assert body["counts"]["missed"] == 0 and body["counts"]["ever_missed"] == 1
    assert body["fatigue"]["missed"] == 1 and body["fatigue"]["non_actionable_share"] == 0.0
    assert body["fatigue"]["ack_p50_s"] is not None and body["fatigue"]["alarms"] == 2
    fatigue = client.get("/api/alarm-fatigue", headers=nurse.headers).json()
    assert [row["missed"] for row in fatigue["shifts"]] == [1]
    csv_text = client.get("/api/handover.csv", headers=nurse.headers)
    assert csv_text.status_code == 200
    assert csv_text.headers["content-type"].startswith("text/csv")
    lines = csv_text.text.splitlines()
    assert lines[0].startswith("# Vigil shift handover,ward ward-a")
    assert lines[2].startswith("section,alarm_id,kind,state,robot_id")
    (row,) = [line for line in lines[3:] if line.startswith(f"resolved,{alarm.id},")]
    assert row.startswith(f"resolved,{alarm.id},emergency,resolved,{robot},ward-a,P-1")
    assert ",true_emergency," in row and ",yes," in row
    # Any ward name an admin asks for downloads (no 500): the file name falls back to ASCII.
    admin = make_account(Role.ADMIN, None, "ada")
    odd = client.get("/api/handover.csv", params={"ward": 'Station "Ü"\n3'}, headers=admin.headers)
    assert odd.status_code == 200, odd.text
    assert 'filename="handover-Station ____3-' in odd.headers["content-disposition"]
    assert (
        "filename*=UTF-8''handover-Station%20%22%C3%9C%22%0A3-"
        in odd.headers["content-disposition"]
    )
    assert events(session_factory, alarm.id)[-4:] == [
        ("miss", "open", "missed", "system"),
        ("escalate", "missed", "missed", "system"),
        ("acknowledge", "missed", "acknowledged", "nurse:nora"),
        ("resolve", "acknowledged", "resolved", "nurse:nora"),
    ]


def unseen(seq: int, transport: str = "t-1"):
    """A frame the robot sent without its patient: every keypoint missing."""
    return frame(seq, "normal", transport).model_copy(
        update={"keypoints": [[0.0, 0.0, 0.0]] * 25, "depth": None, "floor": None}
    )


def test_frames_without_the_patient_raise_patient_not_seen_until_the_patient_is_back(
    client, robot, make_account, session_factory, settings
):
    """A robot whose frames flow but show nobody has lost its patient: after
    patient_unseen_seconds the nurse board gets a technical alarm, which clears itself when a
    frame shows the patient again (not when more empty frames arrive)."""
    settings.patient_unseen_seconds = 4
    nurse = make_account(Role.NURSE, ward="ward-a", username="nina")
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "normal", "t-1"), end=False)
    seen_at = utcnow()
    stream(client, robot, ROBOT_TOKEN, "t-1", unseen(1), end=False)
    assert tick(client, seen_at + timedelta(seconds=3)) == []  # within the grace period

    # Frames keep flowing, none with the patient: one technical alarm for the outage.
    stream(client, robot, ROBOT_TOKEN, "t-1", unseen(2), end=False)
    (lost,) = tick(client, seen_at + timedelta(seconds=4.5))
    assert (lost["kind"], lost["priority"], lost["transport_id"]) == (
        "patient_not_seen",
        "technical",
        "t-1",
    )
    stream(client, robot, ROBOT_TOKEN, "t-1", unseen(3), end=False)
    assert tick(client, utcnow()) == []  # empty frames neither clear it nor raise another
    board = client.get("/api/alarms", headers=nurse.headers).json()
    assert [a["kind"] for a in board if a["state"] == "open"] == ["patient_not_seen"]

    stream(client, robot, ROBOT_TOKEN, "t-1", frame(4, "normal", "t-1"), end=False)
    changed = tick(client, utcnow())
    assert [(a["id"], a["state"]) for a in changed] == [(lost["id"], "resolved")]
    assert clears(session_factory, lost["id"]) == [
        ("open", "resolved", "cleared: patient in view again")
    ]
    assert tick(client, utcnow()) == []


def test_a_transport_that_never_shows_the_patient_raises_patient_not_seen(client, robot, settings):
    settings.patient_unseen_seconds = 4
    stream(client, robot, ROBOT_TOKEN, "t-2", unseen(0, "t-2"), end=False)
    started = utcnow()
    stream(client, robot, ROBOT_TOKEN, "t-2", unseen(1, "t-2"), end=False)
    assert tick(client, started + timedelta(seconds=3)) == []
    stream(client, robot, ROBOT_TOKEN, "t-2", unseen(2, "t-2"), end=False)
    assert [a["kind"] for a in tick(client, started + timedelta(seconds=4.5))] == [
        "patient_not_seen"
    ]


def test_missed_emergency_escalates_on_to_the_wards_further_responders_with_audit(
    client, robot, make_account, session_factory
):
    """Issue 32: a missed Emergency is never left alone: it goes on to the charge nurse, then
    to the rapid-response team (the chain settable per ward), each step in its audit; a nurse
    acknowledging it stops the chain."""
    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b", ward="ward-b", token_hash=hash_robot_token("tok-b")))
    nurse = make_account(Role.NURSE, ward="ward-a", username="nia")
    stream(client, robot, ROBOT_TOKEN, "t-a", frame(0, "emergency", "t-a"))
    stream(client, "robot-b", "tok-b", "t-b", frame(0, "emergency", "t-b"))
    with session_factory() as session:
        alarm_a, alarm_b = session.scalars(select(Alarm).order_by(Alarm.robot_id)).all()
    start = max(alarm_a.raised_at, alarm_b.raised_at)
    # ward-a escalates every 30 s, ward-b every 60 s; two levels, then missed.
    for seconds in (31, 62, 93, 125, 186):
        tick(client, start + timedelta(seconds=seconds))
    with session_factory() as session:
        states = {a.id: (a.state, a.escalated_to) for a in session.scalars(select(Alarm))}
    assert states == {alarm_a.id: (AlarmState.MISSED, None), alarm_b.id: (AlarmState.MISSED, None)}
    missed_at_a = start + timedelta(seconds=93)

    def responders(alarm_id: int) -> list[str]:
        with session_factory() as session:
            rows = session.scalars(
                select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
            )
            return [
                e.comment
                for e in rows
                if e.comment and "escalated to" in e.comment and e.from_state == "missed"
            ]

    assert tick(client, missed_at_a + timedelta(seconds=119)) == []  # (ward-b missed at 186 s)
    first = tick(client, missed_at_a + timedelta(seconds=121))
    assert [(a["id"], a["state"], a["escalated_to"]) for a in first] == [
        (alarm_a.id, "missed", "charge nurse")
    ]
    assert responders(alarm_a.id) == ["missed, unanswered 3 min: escalated to charge nurse"]
    second = tick(client, missed_at_a + timedelta(seconds=242))
    ids = {a["id"]: a["escalated_to"] for a in second}
    assert ids[alarm_a.id] == "rapid-response team"
    assert ids[alarm_b.id] == "charge nurse B"  # ward-b's own chain
    # The chains end: no further step, but the alarm stays missed (and on every board).
    assert tick(client, missed_at_a + timedelta(hours=1)) == []
    assert len(responders(alarm_a.id)) == 2 and len(responders(alarm_b.id)) == 1
    pushed = client.get(f"/api/alarms/{alarm_a.id}", headers=nurse.headers).json()
    assert (pushed["state"], pushed["escalated_to"]) == ("missed", "rapid-response team")

    # Acknowledged at last: the chain stops there (later, only the re-alarm of an acknowledged
    # alarm not resolved in time).
    response = client.post(f"/api/alarms/{alarm_a.id}/acknowledge", headers=nurse.headers)
    assert response.status_code == 200, response.text
    later = tick(client, missed_at_a + timedelta(hours=2))
    assert {(a["id"], a["state"]) for a in later} <= {(alarm_a.id, "acknowledged")}
    assert len(responders(alarm_a.id)) == 2


def test_the_monitor_asks_about_many_outages_in_a_few_queries_and_raises_each_once(
    client, session_factory
):
    """A robot that died mid-transport keeps its outage for hours: a pass costs a few queries
    however many such transports there are (not one or two per transport and second), and so
    does pushing the alarms it raised (not a reload per alarm after the flush)."""
    from sqlalchemy import event

    from backend.models import Transport

    started = utcnow() - timedelta(minutes=5)
    with transaction(session_factory) as session:
        session.add(
            Robot(id="silent", name="silent", ward="ward-a", token_hash=hash_robot_token("x"))
        )
        session.flush()
        for i in range(60):
            session.add(
                Transport(id=f"s-{i}", robot_id="silent", mode="walking", started_at=started)
            )
    statements: list[str] = []

    def count(conn, cursor, statement, *args) -> None:
        statements.append(statement)

    def counted_tick(at) -> list[dict]:
        statements.clear()
        engine = client.app.state.services.engine
        event.listen(engine, "before_cursor_execute", count)
        try:
            return tick(client, at)
        finally:
            event.remove(engine, "before_cursor_execute", count)

    first = counted_tick(utcnow())
    assert sorted(a["transport_id"] for a in first) == sorted(f"s-{i}" for i in range(60))
    assert {a["kind"] for a in first} == {"robot_offline"}
    assert all(a["transport_ended_at"] is None and a["dispositions"] == [] for a in first)
    # Each new alarm costs its INSERTs (alarm, audit event, outbox message); a pass stays
    # short of one more query per alarm.
    inserts = sum(1 for s in statements if s.lstrip().upper().startswith("INSERT"))
    assert len(statements) - inserts <= 20, [s for s in statements if "INSERT" not in s]

    assert counted_tick(utcnow() + timedelta(seconds=5)) == []  # one alarm per outage
    assert len(statements) <= 12, statements


def test_a_robot_whose_frames_wait_on_another_replica_raises_no_patient_not_seen(
    settings, session_factory, robot
):
    """The monitor runs on one replica; a robot streaming to another whose writer is behind
    has stale stored times there. While that replica says the robot's messages wait, the
    monitor raises nothing for it; once it no longer does, the outage is alarmed."""
    settings.patient_unseen_seconds = 4
    settings.redis_url = REDIS_URL
    settings.redis_channel = f"vigil-test-{uuid.uuid4().hex}"
    with TestClient(create_app(settings)) as client:
        stream(client, robot, ROBOT_TOKEN, "t-1", unseen(0), end=False)
        started = utcnow()
        stream(client, robot, ROBOT_TOKEN, "t-1", unseen(1), end=False)
        other = SharedWaiting(
            lambda: frozenset({robot}),
            client.app.state.services.bus.redis,
            f"{settings.redis_channel}.waiting.",
            "other-replica",
        )
        client.portal.call(other.publish)
        assert tick(client, started + timedelta(seconds=4.5)) == []
        client.portal.call(other.stop)
        assert [a["kind"] for a in tick(client, started + timedelta(seconds=4.5))] == [
            "patient_not_seen"
        ]


def test_a_stream_that_is_behind_is_a_stalled_stream_not_a_lost_patient(client, robot, settings):
    """Every frame stored shows the patient, and then none arrive for a while (the robot's
    link or the server is behind): that is no evidence the patient was lost. The monitor
    raises no patient_not_seen, and stream_stalled once the stream is stalled long enough."""
    settings.patient_unseen_seconds = 4
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(0, "normal", "t-1"), end=False)
    stream(client, robot, ROBOT_TOKEN, "t-1", frame(1, "normal", "t-1"), end=False)
    seen_at = utcnow()
    assert tick(client, seen_at + timedelta(seconds=4.5)) == []
    assert [a["kind"] for a in tick(client, seen_at + timedelta(seconds=5.5))] == ["stream_stalled"]
