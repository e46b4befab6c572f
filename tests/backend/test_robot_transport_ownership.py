"""Issue 18, item 3: a robot writes only into its own transports. Every message naming another
robot's transport closes that robot's socket with 4403 and a reason; nothing of the message is
stored, nothing stored before it is lost, and the other robot keeps streaming."""

from __future__ import annotations

import asyncio
import json
import time

import pytest
from sqlalchemy import select
from starlette.websockets import WebSocketDisconnect

from backend.db import transaction
from backend.ingest.received import from_batch
from backend.ingest.writer import FrameWriter
from backend.metrics import Metrics
from backend.models import Alarm, Frame, Robot
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from vigil import protocol
from vigil.protocol import DetectionStatus, FrameBatch, Hello, TransportEnd, TransportStart

OTHER_TOKEN = "robot-b1-token"


@pytest.fixture
def other_robot(session_factory) -> str:
    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b1", ward="ward-b", token_hash=hash_robot_token(OTHER_TOKEN)))
    return "robot-b1"


def connect(ws, robot_id: str, token: str) -> None:
    ws.send_text(Hello(robot_id=robot_id, token=token).model_dump_json())
    assert json.loads(ws.receive_text())["type"] == "welcome"


def start(ws, transport_id: str) -> None:
    ws.send_text(
        TransportStart(
            transport_id=transport_id, mode="walking", ts=0.0, patient="P-b", location="3b-12"
        ).model_dump_json()
    )


def send(ws, frames) -> None:
    ws.send_text(FrameBatch(frames=frames).model_dump_json())


def ack(ws) -> int:
    message = json.loads(ws.receive_text())
    assert message["type"] == "ack", message
    return message["seq"]


def closed_with(ws) -> tuple[int, str]:
    with pytest.raises(WebSocketDisconnect) as closed:
        ws.receive_text()
    return closed.value.code, closed.value.reason


def stored(session_factory, robot_id: str) -> list[int]:
    with session_factory() as session:
        return list(
            session.scalars(select(Frame.seq).where(Frame.robot_id == robot_id).order_by(Frame.seq))
        )


def alarms_of(session_factory, robot_id: str) -> list[Alarm]:
    with session_factory() as session:
        return list(session.scalars(select(Alarm).where(Alarm.robot_id == robot_id)).unique())


def test_frames_tagged_with_another_robots_transport_close_the_socket(
    client, robot, other_robot, session_factory
):
    """The issue's repro: robot-a sends Emergency frames tagged with robot-b1's transport."""
    with (
        client.websocket_connect("/ws/robot") as b,
        client.websocket_connect("/ws/robot") as a,
    ):
        connect(b, other_robot, OTHER_TOKEN)
        start(b, "t-b1")
        send(b, [frame(0, transport="t-b1"), frame(1, transport="t-b1")])
        assert ack(b) == 1
        connect(a, robot, ROBOT_TOKEN)
        start(a, "t-a")
        send(a, [frame(0, transport="t-a")])
        assert ack(a) == 0
        send(a, [frame(1, "emergency", transport="t-b1"), frame(2, "emergency", "t-b1")])
        code, reason = closed_with(a)
        assert code == protocol.CLOSE_FORBIDDEN == 4403
        assert reason == "transport_id t-b1 belongs to another robot"
        # The other robot keeps streaming into its transport.
        send(b, [frame(2, transport="t-b1")])
        assert ack(b) == 2
    assert stored(session_factory, robot) == [0]  # nothing of the batch, nothing lost
    assert stored(session_factory, other_robot) == [0, 1, 2]
    assert alarms_of(session_factory, robot) == []  # no alarm showing the other's patient


def test_a_batch_mixing_own_and_foreign_frames_stores_none_of_them(
    client, robot, other_robot, session_factory
):
    with client.websocket_connect("/ws/robot") as b:
        connect(b, other_robot, OTHER_TOKEN)
        start(b, "t-b1")
        send(b, [frame(0, transport="t-b1")])
        assert ack(b) == 0
    with client.websocket_connect("/ws/robot") as a:
        connect(a, robot, ROBOT_TOKEN)
        start(a, "t-a")
        send(a, [frame(0, transport="t-a"), frame(1, transport="t-b1"), frame(2, transport="t-a")])
        assert closed_with(a)[0] == protocol.CLOSE_FORBIDDEN
    assert stored(session_factory, robot) == []


@pytest.mark.parametrize(
    "message",
    [
        pytest.param(TransportStart(transport_id="t-b1", mode="walking", ts=0.0), id="start"),
        pytest.param(TransportEnd(transport_id="t-b1", ts=1.0), id="end"),
        pytest.param(
            DetectionStatus(ts=1.0, transport_id="t-b1", degraded=True, reason="no depth"),
            id="detection-status",
        ),
    ],
)
def test_every_message_naming_another_robots_transport_is_refused(
    client, robot, other_robot, session_factory, message
):
    with client.websocket_connect("/ws/robot") as b:
        connect(b, other_robot, OTHER_TOKEN)
        start(b, "t-b1")
        send(b, [frame(0, transport="t-b1")])
        assert ack(b) == 0
    with client.websocket_connect("/ws/robot") as a:
        connect(a, robot, ROBOT_TOKEN)
        a.send_text(message.model_dump_json())
        assert closed_with(a) == (
            protocol.CLOSE_FORBIDDEN,
            "transport_id t-b1 belongs to another robot",
        )
    with session_factory() as session:
        assert session.get(Robot, other_robot) is not None
    assert alarms_of(session_factory, robot) == []


def test_a_robot_reconnecting_mid_transport_keeps_streaming_into_it(client, robot, session_factory):
    with client.websocket_connect("/ws/robot") as a:
        connect(a, robot, ROBOT_TOKEN)
        start(a, "t-a")
        send(a, [frame(0, transport="t-a")])
        assert ack(a) == 0
    with client.websocket_connect("/ws/robot") as a:  # a new connection: nothing cached
        connect(a, robot, ROBOT_TOKEN)
        send(a, [frame(1, transport="t-a")])
        assert ack(a) == 1
        send(a, [frame(2, transport="t-a"), frame(3, transport=None)])
        assert ack(a) == 3
    assert stored(session_factory, robot) == [0, 1, 2, 3]


class FakeLink:
    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self.acks: list[int] = []
        self.rejected: list[tuple[int, str]] = []

    async def send_ack(self, seq: int) -> None:
        self.acks.append(seq)

    async def reject(self, code: int, reason: str) -> None:
        self.rejected.append((code, reason))


def test_the_writer_refuses_another_robots_transport_inside_its_transaction(
    client, robot, other_robot, session_factory
):
    """The last word, past the connection's check: the offending robot's work in the flush is
    refused with 4403 and none of it stored; another robot's work in the same flush is."""
    with client.websocket_connect("/ws/robot") as b:
        connect(b, other_robot, OTHER_TOKEN)
        start(b, "t-b1")
        send(b, [frame(0, transport="t-b1")])
        assert ack(b) == 0

    async def flush() -> tuple[FakeLink, FakeLink]:
        class NoEffects:
            async def publish_alarm(self, alarm: dict) -> None:
                pass

            async def push_assignments(self, robot_ids: list[str]) -> None:
                pass

        writer = FrameWriter(session_factory, Metrics(), NoEffects())
        forger, honest = FakeLink(robot), FakeLink(other_robot)
        forged = [frame(5, "emergency", transport="t-b1")]
        await writer.submit(forger, from_batch(FrameBatch(frames=forged)), 0.0)
        honest_frames = [frame(1, "normal", "t-b1")]
        await writer.submit(honest, from_batch(FrameBatch(frames=honest_frames)), 0.0)
        await writer._flush()
        return forger, honest

    forger, honest = asyncio.run(flush())
    assert forger.rejected == [
        (protocol.CLOSE_FORBIDDEN, "transport_id t-b1 belongs to another robot")
    ]
    assert forger.acks == [] and honest.acks == [1]
    assert stored(session_factory, robot) == []
    assert stored(session_factory, other_robot) == [0, 1]
    assert alarms_of(session_factory, robot) == []


def test_over_a_real_socket_the_forger_is_closed_and_the_owner_keeps_streaming(tmp_path):
    """The same repro against uvicorn over TCP: the code and reason reach the robot."""
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect as ws_connect

    from backend.db import make_engine, make_session_factory
    from tests.support.live_backend import ROBOT_ID, ROBOT_TOKEN, LiveServer

    server = LiveServer.create(tmp_path)
    engine = make_engine(server.database_url)
    factory = make_session_factory(engine)
    with transaction(factory) as session:
        session.add(Robot(id="robot-b1", ward="ward-b", token_hash=hash_robot_token(OTHER_TOKEN)))
    server.start()
    try:
        with ws_connect(server.robot_ws_url) as b, ws_connect(server.robot_ws_url) as a:
            b.send(Hello(robot_id="robot-b1", token=OTHER_TOKEN).model_dump_json())
            assert json.loads(b.recv(timeout=10))["type"] == "welcome"
            b.send(TransportStart(transport_id="t-b1", mode="walking", ts=0.0).model_dump_json())
            b.send(FrameBatch(frames=[frame(0, transport="t-b1")]).model_dump_json())
            assert json.loads(b.recv(timeout=10)) == {"type": "ack", "seq": 0}
            a.send(Hello(robot_id=ROBOT_ID, token=ROBOT_TOKEN).model_dump_json())
            assert json.loads(a.recv(timeout=10))["type"] == "welcome"
            a.send(FrameBatch(frames=[frame(0, "emergency", "t-b1")]).model_dump_json())
            with pytest.raises(ConnectionClosed) as closed:
                a.recv(timeout=10)
            assert closed.value.rcvd is not None
            assert (closed.value.rcvd.code, closed.value.rcvd.reason) == (
                protocol.CLOSE_FORBIDDEN,
                "transport_id t-b1 belongs to another robot",
            )
            b.send(FrameBatch(frames=[frame(1, transport="t-b1")]).model_dump_json())
            assert json.loads(b.recv(timeout=10)) == {"type": "ack", "seq": 1}
    finally:
        server.stop()
    assert stored(factory, ROBOT_ID) == []
    assert stored(factory, "robot-b1") == [0, 1]
    assert alarms_of(factory, ROBOT_ID) == []
    engine.dispose()


def test_the_writer_commits_an_emergency_at_once_and_batches_the_rest(
    client, robot, session_factory
):
    """Normal frames wait up to flush_ms to be committed together; a batch with an Emergency
    decision is committed (and its alarm pushed) without waiting."""
    with client.websocket_connect("/ws/robot") as a:
        connect(a, robot, ROBOT_TOKEN)
        start(a, "t-u")
        send(a, [frame(0, transport="t-u")])
        assert ack(a) == 0

    async def run() -> tuple[list[int], list[int]]:
        class NoEffects:
            async def publish_alarm(self, alarm: dict) -> None:
                pass

            async def push_assignments(self, robot_ids: list[str]) -> None:
                pass

        writer = FrameWriter(session_factory, Metrics(), NoEffects(), flush_ms=60_000)
        link = FakeLink(robot)
        writer.start()
        try:
            await writer.submit(
                link,
                from_batch(FrameBatch(frames=[frame(1, transport="t-u")])),
                time.perf_counter(),
            )
            await asyncio.sleep(0.5)
            lingering = list(link.acks)
            emergency = [frame(2, "emergency", transport="t-u")]
            await writer.submit(link, from_batch(FrameBatch(frames=emergency)), time.perf_counter())
            for _ in range(100):
                if link.acks:
                    break
                await asyncio.sleep(0.05)
            return lingering, list(link.acks)
        finally:
            await writer.stop()

    lingering, acked = asyncio.run(run())
    assert lingering == []  # normal frames wait for their batch (flush_ms)
    assert acked == [2]  # the Emergency took them along at once
    assert stored(session_factory, robot) == [0, 1, 2]
    assert [a.kind for a in alarms_of(session_factory, robot)] == ["emergency"]
