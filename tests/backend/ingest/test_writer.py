"""The frame writer commits a long queue in bounded parts (backend.ingest.writer)."""

from __future__ import annotations

import asyncio
import time

from sqlalchemy import select

from backend.db import transaction
from backend.ingest import context
from backend.ingest import writer as writer_module
from backend.ingest.received import from_batch
from backend.ingest.writer import FrameWriter
from backend.metrics import Metrics
from backend.models import Robot
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.ingest.test_failopen import Link, emergency
from tests.backend.test_first_alarm import frame
from tests.backend.test_robot_transport_ownership import (
    FakeLink,
    ack,
    connect,
    send,
    start,
    stored,
)
from vigil.protocol import FrameBatch, Hello


class NoEffects:
    async def publish_alarm(self, alarm: dict) -> None:
        pass

    async def push_assignments(self, robot_ids: list[str]) -> None:
        pass


def test_a_long_queue_is_committed_in_parts_in_order_each_acknowledged(
    client, robot, session_factory
):
    """Seven one-frame messages behind a writer that takes at most three frames a commit: the
    first commit stores and acknowledges the oldest three only, the Emergency further back
    still makes the rest urgent, and stopping commits the rest in two more parts, in order."""
    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot, ROBOT_TOKEN)
        start(ws, "t-q")
        send(ws, [frame(0, transport="t-q")])
        assert ack(ws) == 0

    async def run() -> tuple[list[int], list[int], bool, list[int], list[int]]:
        writer = FrameWriter(
            session_factory, Metrics(), NoEffects(), flush_ms=60_000, max_flush_frames=3
        )
        link = FakeLink(robot)
        for seq in range(1, 8):
            decision = "emergency" if seq == 6 else "normal"
            batch = from_batch(FrameBatch(frames=[frame(seq, decision, transport="t-q")]))
            await writer.submit(link, batch, 0.0)
        await writer._flush()
        first_acks, first_stored = list(link.acks), stored(session_factory, robot)
        still_urgent = writer._urgent
        writer._task = asyncio.create_task(asyncio.sleep(0))  # as if started: stop() drains
        await writer.stop()
        return (
            first_acks,
            first_stored,
            still_urgent,
            list(link.acks),
            stored(session_factory, robot),
        )

    first_acks, first_stored, still_urgent, acks, rows = asyncio.run(run())
    assert first_acks == [3] and first_stored == [0, 1, 2, 3]
    assert still_urgent  # the Emergency (seq 6) is still queued: the next commit waits for nothing
    assert acks == [3, 6, 7]
    assert rows == list(range(8))


def test_a_message_larger_than_the_bound_is_still_committed_whole(client, robot, session_factory):
    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot, ROBOT_TOKEN)
        start(ws, "t-big")
        send(ws, [frame(0, transport="t-big")])
        assert ack(ws) == 0

    async def run() -> list[int]:
        writer = FrameWriter(session_factory, Metrics(), NoEffects(), max_flush_frames=2)
        link = FakeLink(robot)
        frames = [frame(seq, transport="t-big") for seq in range(1, 6)]
        await writer.submit(link, from_batch(FrameBatch(frames=frames)), 0.0)
        await writer._flush()
        return list(link.acks)

    assert asyncio.run(run()) == [5]
    assert stored(session_factory, robot) == list(range(6))


def test_robots_queued_during_a_blocked_write_each_get_one_storage_stalled_alarm(session_factory):
    """While one write stays blocked, the watch raises storage_stalled for the robots whose
    frames wait, and later for each robot that queues behind it, each once."""

    async def run() -> list[list[str]]:
        writer = FrameWriter(session_factory, Metrics(), NoEffects(), storage_stall_s=2.0)
        writer._inflight = [emergency("r1", 1, 0.0)]
        writer.fail_open.on_write_start(0.0)
        seen = [writer.fail_open.due(2.5, writer._waiting_wards)]
        await writer.submit(Link("r2"), emergency("r2", 1, 2.55).message, 2.55)
        await writer.submit(Link("r1"), emergency("r1", 2, 2.56).message, 2.56)
        seen.append(writer.fail_open.due(2.6, writer._waiting_wards))
        seen.append(writer.fail_open.due(2.7, writer._waiting_wards))
        return [
            sorted(a["robot_id"] for a in pushed if a["kind"] == "storage_stalled")
            for pushed in seen
        ]

    assert asyncio.run(run()) == [["r1"], ["r2"], []]


def test_hellos_of_many_robots_in_one_commit_store_each_agent_and_inputs(session_factory):
    """A reconnect storm's hellos are written back together: each robot keeps its own agent
    version and inputs, none said stays None (keypoints only)."""
    robot_ids = [f"storm-{i}" for i in range(5)]
    with transaction(session_factory) as session:
        for robot_id in robot_ids:
            session.add(Robot(id=robot_id, ward="ward-a", token_hash=hash_robot_token("t")))

    async def run() -> None:
        writer = FrameWriter(session_factory, Metrics(), NoEffects())
        for i, robot_id in enumerate(robot_ids):
            inputs = ["keypoints", "depth"][: i % 3] or None
            hello = Hello(robot_id=robot_id, token="t", agent_version=f"1.{i}", inputs=inputs)
            await writer.submit(FakeLink(robot_id), hello, 0.0)
        await writer._flush()

    asyncio.run(run())
    with session_factory() as session:
        rows = session.execute(
            select(Robot.id, Robot.agent_version, Robot.inputs, Robot.last_seen_at)
            .where(Robot.id.in_(robot_ids))
            .order_by(Robot.id)
        ).all()
    assert [(r.id, r.agent_version, r.inputs) for r in rows] == [
        ("storm-0", "1.0", None),
        ("storm-1", "1.1", ["keypoints"]),
        ("storm-2", "1.2", ["keypoints", "depth"]),
        ("storm-3", "1.3", None),
        ("storm-4", "1.4", ["keypoints"]),
    ]
    assert all(r.last_seen_at is not None for r in rows)


def test_an_emergency_already_stored_does_not_make_every_message_a_commit(
    client, robot, session_factory
):
    """A robot stopped in Emergency keeps deciding Emergency: once its alarm is stored, its
    messages batch like any other (they fold into the alarm). The first Emergency is urgent,
    and so is the first of a transport without a stored one; after a resolve the next
    Emergency opens a new alarm at the next flush."""
    from backend.models import Alarm, AlarmState

    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot, ROBOT_TOKEN)
        start(ws, "t-e")
        start(ws, "t-f")
        send(ws, [frame(0, transport="t-e")])
        assert ack(ws) == 0

    def submitted(writer, link, seq: int, transport: str = "t-e") -> bool:
        batch = from_batch(FrameBatch(frames=[frame(seq, "emergency", transport=transport)]))
        asyncio.run(writer.submit(link, batch, 0.0))
        return writer._urgent

    writer = FrameWriter(session_factory, Metrics(), NoEffects(), flush_ms=60_000)
    link = FakeLink(robot)
    assert submitted(writer, link, 1)  # no alarm stored yet
    asyncio.run(writer._flush())
    assert not submitted(writer, link, 2)  # folds into the stored alarm: waits for a batch
    assert writer.fail_open.unstored == {}  # and needs no provisional card if it is slow
    assert submitted(writer, link, 3, "t-f")  # another transport's first Emergency
    asyncio.run(writer._flush())
    with transaction(session_factory) as session:
        for alarm in session.scalars(select(Alarm).where(Alarm.transport_key == "t-e")):
            alarm.state = AlarmState.RESOLVED  # resolved by a nurse, on another replica
    submitted(writer, link, 4)
    asyncio.run(writer._flush())
    with session_factory() as session:
        alarms = session.scalars(select(Alarm).where(Alarm.transport_key == "t-e")).all()
        assert sorted(a.state for a in alarms) == ["open", "resolved"]
    assert not submitted(writer, link, 5)
    # Not trusted for longer than a storage stall: then every Emergency is watched again.
    writer._alarmed_trust_s = 0.0
    assert submitted(writer, link, 6)
    assert list(writer.fail_open.unstored) == [f"{robot}/t-e/emergency"]


class Pushes:
    """The alarms the writer pushed to the boards, in order."""

    def __init__(self) -> None:
        self.alarms: list[dict] = []

    async def publish_alarm(self, alarm: dict) -> None:
        self.alarms.append(alarm)

    async def push_assignments(self, robot_ids: list[str]) -> None:
        pass


def test_a_continuing_emergency_is_pushed_once_per_period_and_ends_on_its_last_decision(
    client, robot, session_factory, monkeypatch
):
    """A robot deciding Emergency ten times a second: its alarm reaches the boards when raised,
    then at most once per UPDATE_PUSH_S (the flush that folds the next frame pushes it; the
    storage watch's trailing push does not push it a second time), and once the robot stops,
    the trailing push brings the boards its last decision."""
    monkeypatch.setattr(context, "UPDATE_PUSH_S", 0.2)
    monkeypatch.setattr(writer_module, "TRAILING_PUSH_GRACE_S", 0.3)
    with client.websocket_connect("/ws/robot") as ws:
        connect(ws, robot, ROBOT_TOKEN)
        start(ws, "t-e")
        send(ws, [frame(0, transport="t-e")])
        assert ack(ws) == 0

    async def run() -> tuple[list[dict], float, list[dict]]:
        pushes = Pushes()
        writer = FrameWriter(session_factory, Metrics(), pushes)
        link = FakeLink(robot)
        started = time.monotonic()
        for seq in range(1, 21):  # 2 s at 10 Hz
            batch = from_batch(FrameBatch(frames=[frame(seq, "emergency", transport="t-e")]))
            await writer.submit(link, batch, time.perf_counter())
            await writer._trailing_pushes()  # the storage watch's tick, then the flush
            await writer._flush()
            await asyncio.sleep(0.1)
        streaming = list(pushes.alarms)
        elapsed = time.monotonic() - started
        await asyncio.sleep(0.6)  # the robot stopped: period and grace are up
        await writer._trailing_pushes()
        return streaming, elapsed, pushes.alarms[len(streaming) :]

    streaming, elapsed, after = asyncio.run(run())
    assert {a["id"] for a in streaming + after} == {streaming[0]["id"]}  # one alarm
    assert streaming[0]["state"] == "open"
    # raised, then one push per 0.2 s period (the old trailing push made about two)
    assert len(streaming) <= 2 + elapsed / 0.2
    assert [a["last_seq"] for a in after] == [20]
