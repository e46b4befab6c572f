"""Robot websocket hardening: every kind of bad input closes that connection with a clear code
and reason; frames already stored stay, and another robot keeps streaming meanwhile."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sqlalchemy import func, select
from starlette.websockets import WebSocketDisconnect

from backend.db import transaction
from backend.models import Frame, Robot, Role
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from vigil import protocol
from vigil.protocol import FrameBatch, Hello

OTHER_TOKEN = "other-robot-token"


@pytest.fixture
def other_robot(session_factory) -> str:
    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b", ward="ward-a", token_hash=hash_robot_token(OTHER_TOKEN)))
    return "robot-b"


def hello(ws, robot_id: str, token: str) -> dict:
    ws.send_text(Hello(robot_id=robot_id, token=token).model_dump_json())
    return json.loads(ws.receive_text())


def send_frames(ws, *seqs: int) -> dict:
    ws.send_text(FrameBatch(frames=[frame(s) for s in seqs]).model_dump_json())
    return json.loads(ws.receive_text())


def closed_with(ws) -> tuple[int, str]:
    with pytest.raises(WebSocketDisconnect) as closed:
        ws.receive_text()
    return closed.value.code, closed.value.reason


def valid_frame_dict(seq: int) -> dict:
    return json.loads(frame(seq).model_dump_json())


def frames_message(**changes) -> str:
    record = valid_frame_dict(100) | changes
    return json.dumps({"type": "frames", "frames": [record]})


BAD_MESSAGES = [
    pytest.param(b"\x00\xff\x13binary noise", protocol.CLOSE_BAD_MESSAGE, "binary", id="binary"),
    pytest.param(
        '{"type": "frames", "frames": [{"seq": 1',
        protocol.CLOSE_BAD_MESSAGE,
        "not valid JSON",
        id="truncated-json",
    ),
    pytest.param(
        '{"type": "teleport"}',
        protocol.CLOSE_BAD_MESSAGE,
        "unknown message type",
        id="unknown-type",
    ),
    pytest.param("[1, 2, 3]", protocol.CLOSE_BAD_MESSAGE, "JSON object", id="not-an-object"),
    pytest.param(
        json.dumps({"type": "frames", "frames": [{"seq": 1, "ts": 1.0}]}),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.keypoints",
        id="missing-field",
    ),
    pytest.param(
        frames_message(ts=None).replace('"ts": null', '"ts": NaN'),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.ts",
        id="nan",
    ),
    pytest.param(
        frames_message(keypoints=[[1.0, 2.0, 0.5]] * 24),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.keypoints",
        id="24-keypoints",
    ),
    pytest.param(
        frames_message(keypoints=[[1.0, 2.0]] * 25),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.keypoints.0",
        id="2-values-per-keypoint",
    ),
    pytest.param(
        frames_message(depth=[1.0] * 26),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.depth",
        id="26-depths",
    ),
    pytest.param(
        frames_message(floor=[1.0, 0.5]),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.floor",
        id="2-floor-measures",
    ),
    pytest.param(
        frames_message(decision="panic"),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.decision",
        id="unknown-decision",
    ),
    pytest.param(
        frames_message(seq=-1), protocol.CLOSE_BAD_MESSAGE, "frames.0.seq", id="negative-seq"
    ),
    # Strict types: a number sent as a string is the robot's bug, not something to guess at.
    pytest.param(
        frames_message(seq="12"), protocol.CLOSE_BAD_MESSAGE, "frames.0.seq", id="string-seq"
    ),
    pytest.param(
        frames_message(ts="1.5"), protocol.CLOSE_BAD_MESSAGE, "frames.0.ts", id="string-ts"
    ),
    pytest.param(
        frames_message(delay_ms="5"),
        protocol.CLOSE_BAD_MESSAGE,
        "frames.0.delay_ms",
        id="string-delay",
    ),
    # A start or end time no datetime can hold was closed with 1011 (server error) before.
    pytest.param(
        json.dumps(
            {"type": "transport_start", "transport_id": "t-far", "mode": "walking", "ts": 1e300}
        ),
        protocol.CLOSE_BAD_MESSAGE,
        "invalid ts",
        id="start-ts-1e300",
    ),
    pytest.param(
        json.dumps(
            {"type": "transport_start", "transport_id": "t-before", "mode": "walking", "ts": -1e12}
        ),
        protocol.CLOSE_BAD_MESSAGE,
        "invalid ts",
        id="start-ts-negative",
    ),
    pytest.param(
        json.dumps({"type": "transport_end", "transport_id": "t-far", "ts": 1e300}),
        protocol.CLOSE_BAD_MESSAGE,
        "invalid ts",
        id="end-ts-1e300",
    ),
    pytest.param(
        " " * (protocol.MAX_MESSAGE_BYTES + 1) + "{}",
        protocol.CLOSE_TOO_LARGE,
        "exceeds",
        id="oversized",
    ),
    pytest.param(
        Hello(robot_id="robot-a", token=ROBOT_TOKEN).model_dump_json(),
        protocol.CLOSE_BAD_MESSAGE,
        "hello sent twice",
        id="second-hello",
    ),
]


@pytest.mark.parametrize(("message", "code", "reason"), BAD_MESSAGES)
def test_bad_message_closes_only_that_connection_and_keeps_stored_frames(
    client, robot, other_robot, session_factory, message, code, reason
):
    with (
        client.websocket_connect("/ws/robot") as bad,
        client.websocket_connect("/ws/robot") as good,
    ):
        hello(bad, robot, ROBOT_TOKEN)
        hello(good, other_robot, OTHER_TOKEN)
        assert send_frames(bad, 0, 1) == {"type": "ack", "seq": 1}
        assert send_frames(good, 0) == {"type": "ack", "seq": 0}

        if isinstance(message, bytes):
            bad.send_bytes(message)
        else:
            bad.send_text(message)
        closed_code, closed_reason = closed_with(bad)
        assert closed_code == code
        assert reason in closed_reason

        # The other robot is still served.
        assert send_frames(good, 1, 2) == {"type": "ack", "seq": 2}

    with session_factory() as session:
        stored = session.execute(select(Frame.robot_id, Frame.seq).order_by(Frame.id)).all()
    assert sorted(stored) == [
        ("robot-a", 0),
        ("robot-a", 1),
        ("robot-b", 0),
        ("robot-b", 1),
        ("robot-b", 2),
    ]


@pytest.mark.parametrize(
    ("first", "code", "reason"),
    [
        (
            Hello(robot_id="robot-a", token="wrong").model_dump_json(),
            protocol.CLOSE_UNAUTHORIZED,
            "token",
        ),
        (
            Hello(robot_id="nobody", token="x").model_dump_json(),
            protocol.CLOSE_UNAUTHORIZED,
            "unknown robot",
        ),
        (
            Hello(robot_id="robot-a", token=ROBOT_TOKEN, protocol=99).model_dump_json(),
            protocol.CLOSE_PROTOCOL_VERSION,
            "protocol 99",
        ),
        (
            FrameBatch(frames=[frame(0)]).model_dump_json(),
            protocol.CLOSE_BAD_MESSAGE,
            "first message must be hello",
        ),
        ('{"type": "hello", "robot_id": "robot-a"}', protocol.CLOSE_BAD_MESSAGE, "token"),
    ],
)
def test_bad_hello_is_refused_with_a_reason(client, robot, first, code, reason):
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(first)
        closed_code, closed_reason = closed_with(ws)
    assert closed_code == code
    assert reason in closed_reason


def test_hello_timeout(client, robot):
    client.app.state.services.settings.robot_hello_timeout_s = 0.2
    with client.websocket_connect("/ws/robot") as ws:
        assert closed_with(ws) == (protocol.CLOSE_HELLO_TIMEOUT, "no hello received in time")


def test_second_connection_of_a_robot_replaces_the_first(client, robot, session_factory):
    with client.websocket_connect("/ws/robot") as first:
        hello(first, robot, ROBOT_TOKEN)
        assert send_frames(first, 0, 1) == {"type": "ack", "seq": 1}
        with client.websocket_connect("/ws/robot") as second:
            assert hello(second, robot, ROBOT_TOKEN)["last_seq"] == 1
            assert closed_with(first) == (protocol.CLOSE_REPLACED, "replaced by a newer connection")
            # The replay of an already stored frame is acknowledged, not stored twice.
            assert send_frames(second, 1, 2) == {"type": "ack", "seq": 2}
    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Frame)) == 3


def test_revoked_token_closes_the_live_connection(client, robot, make_account):
    admin = make_account(Role.ADMIN, ward=None)
    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        response = client.delete(f"/api/robots/{robot}/token", headers=admin.headers)
        assert response.status_code == 204
        assert closed_with(ws) == (protocol.CLOSE_UNAUTHORIZED, "robot token revoked")
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert closed_with(ws)[0] == protocol.CLOSE_UNAUTHORIZED


def test_transport_of_another_robot_is_refused(client, robot, other_robot, session_factory):
    start = protocol.TransportStart(transport_id="t-x", mode="walking", ts=0.0)
    with client.websocket_connect("/ws/robot") as a:
        hello(a, robot, ROBOT_TOKEN)
        a.send_text(start.model_dump_json())
        assert send_frames(a, 0) == {"type": "ack", "seq": 0}
    with client.websocket_connect("/ws/robot") as b:
        hello(b, other_robot, OTHER_TOKEN)
        b.send_text(start.model_dump_json())
        code, reason = closed_with(b)
    assert code == protocol.CLOSE_FORBIDDEN
    assert "belongs to another robot" in reason


def test_frames_are_stored_compactly_and_readable_by_range(
    client, robot, make_account, session_factory
):
    annotator = make_account(Role.ANNOTATOR)
    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        ws.send_text(
            protocol.TransportStart(transport_id="t-1", mode="walking", ts=0.0).model_dump_json()
        )
        assert send_frames(ws, *range(10)) == {"type": "ack", "seq": 9}
    with session_factory() as session:
        stored = session.scalars(select(Frame).order_by(Frame.index)).all()
        assert {len(f.keypoints) for f in stored} == {25 * 3 * 4}
        assert {len(f.depth) for f in stored} == {25 * 4}
        assert {len(f.floor) for f in stored} == {3 * 4}
        video_id = stored[0].video_id
    response = client.get(
        f"/api/videos/{video_id}/frames", params={"start": 3, "end": 5}, headers=annotator.headers
    )
    assert response.status_code == 200, response.text
    frames = response.json()
    assert [f["index"] for f in frames] == [3, 4, 5]
    assert [f["seq"] for f in frames] == [3, 4, 5]
    sent = frame(4)
    assert np.allclose(frames[1]["keypoints"], sent.keypoints)
    assert frames[1]["depth"][:24] == [2.0] * 24 and frames[1]["depth"][24] is None
    assert frames[1]["floor"] == [1.5, 0.75, None]
    assert frames[1]["scores"] == {"normal": 0.9}


def test_unstorable_text_is_a_bad_message_not_a_server_error(client, robot, other_robot):
    """A NUL byte is valid JSON but PostgreSQL cannot store it in text: 4400 with a reason.
    SQLite stores it. Either way the server does not fail and the other robot is served."""
    with (
        client.websocket_connect("/ws/robot") as ws,
        client.websocket_connect("/ws/robot") as good,
    ):
        hello(ws, robot, ROBOT_TOKEN)
        hello(good, other_robot, OTHER_TOKEN)
        ws.send_text(frames_message(model_version="m\u0000"))
        if client.app.state.services.engine.dialect.name == "postgresql":
            code, reason = closed_with(ws)
            assert code == protocol.CLOSE_BAD_MESSAGE and "cannot be stored" in reason
        else:
            assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 100}
        assert send_frames(good, 0) == {"type": "ack", "seq": 0}


@pytest.mark.parametrize("field", ["seq", "delay_ms"])
def test_integer_beyond_the_column_is_refused_not_wrapped(client, robot, session_factory, field):
    """PostgreSQL's frames.seq and delay_ms are 32-bit; the binary COPY must not store the low
    bits of a larger value (2**32 + 5 as 5). SQLite's integers are 64-bit: stored as sent."""
    value = 2**32 + 5
    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        ws.send_text(frames_message(**{field: value}))
        if client.app.state.services.engine.dialect.name == "postgresql":
            code, reason = closed_with(ws)
            assert code == protocol.CLOSE_BAD_MESSAGE and "cannot be stored" in reason
        else:
            ack = json.loads(ws.receive_text())
            assert ack == {"type": "ack", "seq": value if field == "seq" else 100}
    with session_factory() as session:
        stored = session.scalars(select(getattr(Frame, field))).all()
    assert stored == (
        [] if client.app.state.services.engine.dialect.name == "postgresql" else [value]
    )


def test_metrics_count_frames_ack_latency_open_alarms_and_robots(client, robot, make_account):
    engineer = make_account(Role.ENGINEER, ward=None)
    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        ws.send_text(FrameBatch(frames=[frame(0), frame(1, "emergency")]).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 1}
        text = client.get("/metrics", headers=engineer.headers).text
    metrics = {
        line.split(" ")[0]: float(line.split(" ")[1])
        for line in text.splitlines()
        if line and not line.startswith("#")
    }
    assert metrics["vigil_frames_ingested_total"] == 2
    # The frames' commit, and the hello's (its fields are stored by the writer after the
    # welcome) unless it went in the same batch.
    assert metrics["vigil_ingest_commit_seconds_count"] in (1, 2)
    assert metrics['vigil_open_alarms{kind="emergency"}'] == 1
    assert metrics["vigil_connected_robots"] == 1


def test_frames_written_by_another_replica_meanwhile_are_neither_duplicated_nor_clobbered(
    client, robot, session_factory
):
    """The writer keeps robot and video rows between flushes; when another replica wrote for
    the same robot in between, the conflict is detected and the batch retried on fresh rows."""
    from backend.ingest import service
    from backend.ingest.received import compact_all

    # A frame keeps its capture time when it is sent again (the robot's outbox stores it); on
    # PostgreSQL the unique key is (robot, seq, ts), ts being the day partitions' key.
    def same_frame(seq: int):
        return frame(seq).model_copy(update={"ts": 1_000_000.0 + seq})

    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        ws.send_text(
            protocol.TransportStart(transport_id="t-1", mode="walking", ts=0.0).model_dump_json()
        )
        assert send_frames(ws, 0, 1) == {"type": "ack", "seq": 1}
        with transaction(session_factory) as session:  # "replica B" stores 2 and 3
            service.store_frames(
                session, session.get(Robot, robot), compact_all([same_frame(2), same_frame(3)])
            )
        ws.send_text(FrameBatch(frames=[same_frame(s) for s in (2, 3, 4, 5)]).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 5}
    with session_factory() as session:
        rows = session.execute(select(Frame.seq, Frame.index).order_by(Frame.seq)).all()
    assert [seq for seq, _ in rows] == [0, 1, 2, 3, 4, 5]
    assert sorted(index for _, index in rows) == [0, 1, 2, 3, 4, 5]


def test_an_emergency_under_a_reused_sequence_number_still_raises_its_alarm(
    client, robot, session_factory
):
    """A sender that numbers from 0 again (it ignored the welcome's last_seq) reuses sequence
    numbers: those frames are not stored over the stored ones, but a fall they report must
    still reach the nurse. The same frames sent again (same capture times) change nothing."""
    from backend.models import Alarm

    def at(seq: int, ts: float, decision: str = "normal"):
        return frame(seq, decision).model_copy(update={"ts": ts})

    def emergencies() -> list[tuple[int, int | None]]:
        with session_factory() as session:
            return session.execute(
                select(Alarm.decision_count, Alarm.last_seq).where(Alarm.kind == "emergency")
            ).all()

    with client.websocket_connect("/ws/robot") as ws:
        hello(ws, robot, ROBOT_TOKEN)
        ws.send_text(
            protocol.TransportStart(transport_id="t-1", mode="walking", ts=0.0).model_dump_json()
        )
        stored = [at(s, 1000.0 + s) for s in range(4)]
        ws.send_text(FrameBatch(frames=stored).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 3}
        # the same frames again, one of them now carrying another decision: a resend
        resend = [*stored[:2], stored[2].model_copy(update={"decision": "emergency"})]
        ws.send_text(FrameBatch(frames=resend).model_dump_json())
        json.loads(ws.receive_text())
        assert emergencies() == []
        # seq 2 used again for a later frame that reports a fall
        ws.send_text(FrameBatch(frames=[at(2, 2000.0, "emergency")]).model_dump_json())
        json.loads(ws.receive_text())
        assert emergencies() == [(1, 2)]
    with session_factory() as session:
        rows = session.execute(select(Frame.seq, Frame.ts, Frame.decision).order_by(Frame.seq))
        assert [(s, ts, d) for s, ts, d in rows] == [(s, 1000.0 + s, "normal") for s in range(4)]
