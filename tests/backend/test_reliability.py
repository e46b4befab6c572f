"""Reliability with the real backend (uvicorn subprocesses on free ports, the test database):
kill -9 while a robot streams, two replicas fanning alarms out through Redis, garbage on the
robot websocket."""

from __future__ import annotations

import asyncio
import json
import os
import time
import uuid

import httpx
import pytest
from sqlalchemy import func, select
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

from backend.db import transaction
from backend.models import Frame
from backend.process import BackendProcess
from tests.backend.conftest import ROBOT_TOKEN, SUBPROCESS_SECRET
from tests.backend.test_first_alarm import frame
from vigil import protocol
from vigil.protocol import FrameBatch, Hello, TransportStart

REDIS_URL = os.environ.get("VIGIL_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")


@pytest.fixture
def backend_env(database_url, tmp_path) -> dict[str, str]:
    return {
        "VIGIL_DATABASE_URL": database_url,
        "VIGIL_SECRET_KEY": SUBPROCESS_SECRET,
        "VIGIL_FRONTEND_DIR": str(tmp_path / "no-frontend"),
        "VIGIL_STREAM_STALL_SECONDS": "120",
        "VIGIL_ROBOT_OFFLINE_SECONDS": "120",
    }


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


async def robot_hello(ws) -> dict:
    await ws.send(Hello(robot_id="robot-a", token=ROBOT_TOKEN).model_dump_json())
    welcome = json.loads(await ws.recv())
    assert welcome["type"] == "welcome"
    return welcome


async def wait_for_alarm(ws, predicate, timeout_s: float = 10) -> dict:
    """Read snapshot and alarm messages until one alarm satisfies `predicate`."""
    deadline = time.monotonic() + timeout_s
    while True:
        remaining = deadline - time.monotonic()
        assert remaining > 0, "the alarm never reached the nurse"
        message = json.loads(await asyncio.wait_for(ws.recv(), remaining))
        alarms = message.get("alarms", []) + ([message["alarm"]] if "alarm" in message else [])
        for alarm in alarms:
            if predicate(alarm):
                return alarm


def seq_counts(session_factory) -> dict[int, int]:
    with session_factory() as session:
        rows = session.execute(
            select(Frame.seq, func.count()).where(Frame.robot_id == "robot-a").group_by(Frame.seq)
        ).all()
    return dict(rows)


@pytest.mark.timeout(120)
def test_kill_9_loses_no_acknowledged_frame_and_the_emergency_reaches_the_nurse(
    backend_env, robot, nurse_token, session_factory, tmp_path
):
    backend = BackendProcess(backend_env, log_path=tmp_path / "backend.log").start()
    sent: dict[int, str] = {}
    acked = -1
    emergency_seq = None

    async def stream_until_killed() -> None:
        nonlocal acked, emergency_seq
        async with connect(f"{backend.ws}/ws/robot") as ws:
            await robot_hello(ws)
            await ws.send(
                TransportStart(
                    transport_id="t-crash", mode="wheelchair", patient="P-9", ts=0.0
                ).model_dump_json()
            )

            async def read_acks() -> None:
                nonlocal acked
                async for raw in ws:
                    message = json.loads(raw)
                    if message["type"] == "ack":
                        acked = max(acked, message["seq"])

            reader = asyncio.create_task(read_acks())
            seq = 0
            try:
                while True:
                    decision = "normal"
                    if emergency_seq is None and acked >= 300:
                        decision, emergency_seq = "emergency", seq
                    batch = [frame(s, decision, "t-crash") for s in range(seq, seq + 10)]
                    text = FrameBatch(frames=batch).model_dump_json()
                    for record in batch:
                        sent[record.seq] = record.model_dump_json()
                    await ws.send(text)
                    seq += 10
                    if emergency_seq is not None and seq > emergency_seq + 10:
                        # The Emergency went out a moment ago: crash the backend now.
                        await asyncio.to_thread(backend.kill)
                    await asyncio.sleep(0.003)
            except ConnectionClosed:
                pass
            reader.cancel()

    asyncio.run(stream_until_killed())
    acked_before_crash = acked
    assert acked_before_crash >= 300 and emergency_seq is not None
    assert backend.process.returncode == -9

    # Every acknowledged frame survived, exactly once.
    counts = seq_counts(session_factory)
    assert all(counts.get(s) == 1 for s in range(acked_before_crash + 1)), "acked frame lost"
    assert set(counts.values()) == {1}

    backend.start()  # same port, same database
    try:

        async def recover() -> dict:
            async with connect(
                f"{backend.ws}/ws/browser", additional_headers=bearer(nurse_token)
            ) as nurse:
                async with connect(f"{backend.ws}/ws/robot") as ws:
                    welcome = await robot_hello(ws)
                    assert welcome["last_seq"] >= acked_before_crash
                    # The robot re-sends everything not acknowledged (some of it is stored).
                    unacked = [json.loads(sent[s]) for s in sorted(sent) if s > acked_before_crash]
                    for i in range(0, len(unacked), 50):
                        await ws.send(json.dumps({"type": "frames", "frames": unacked[i : i + 50]}))
                    last = max(sent)
                    while True:
                        message = json.loads(await asyncio.wait_for(ws.recv(), 10))
                        if message["type"] == "ack" and message["seq"] == last:
                            break
                return await wait_for_alarm(
                    nurse,
                    lambda a: a["kind"] == "emergency" and a["transport_id"] == "t-crash",
                )

        alarm = asyncio.run(recover())
    finally:
        backend.stop()
    assert alarm["first_seq"] == emergency_seq
    assert alarm["state"] == "open" and alarm["patient"] == "P-9"
    counts = seq_counts(session_factory)
    assert sorted(counts) == sorted(sent) and set(counts.values()) == {1}


@pytest.mark.timeout(90)
def test_two_replicas_fan_alarms_out_through_redis(
    backend_env, robot, nurse_token, session_factory, tmp_path
):
    """And the alarm distribution runs on one of them: a change made on the other reaches the
    Alert Manager through the leader's sender, woken by the change on the bus (its own poll is
    set to a minute here, so nothing else could have sent it)."""
    from tests.backend.distribution.conftest import ThreadedAlertManager
    from tests.support.live_backend import free_port

    manager = ThreadedAlertManager(free_port(), deliver_after_s=None, read_after_s=None)
    manager.start()
    env = backend_env | {
        "VIGIL_REDIS_URL": REDIS_URL,
        "VIGIL_REDIS_CHANNEL": f"vigil-test-{uuid.uuid4().hex}",
        "VIGIL_ALERT_MANAGER": f"127.0.0.1:{manager.simulator.port}",
        "VIGIL_ALERT_POLL_S": "60",
    }
    with (
        BackendProcess(env, log_path=tmp_path / "a.log") as replica_a,
        BackendProcess(env, log_path=tmp_path / "b.log") as replica_b,
    ):
        duties = [
            httpx.get(f"{r.http}/api/health").json()["duties"] for r in (replica_a, replica_b)
        ]
        assert [d["leading"] for d in duties] == [True, False]

        async def scenario() -> tuple[dict, dict]:
            async with (
                connect(
                    f"{replica_b.ws}/ws/browser", additional_headers=bearer(nurse_token)
                ) as nurse_on_b,
                connect(
                    f"{replica_a.ws}/ws/browser", additional_headers=bearer(nurse_token)
                ) as nurse_on_a,
                connect(f"{replica_a.ws}/ws/robot") as ws,
            ):
                assert json.loads(await nurse_on_b.recv())["alarms"] == []
                assert json.loads(await nurse_on_a.recv())["alarms"] == []
                await robot_hello(ws)
                await ws.send(FrameBatch(frames=[frame(0, "emergency")]).model_dump_json())
                assert json.loads(await ws.recv()) == {"type": "ack", "seq": 0}
                # Robot on replica A, nurse on replica B.
                raised = await wait_for_alarm(nurse_on_b, lambda a: a["kind"] == "emergency")

                # Acknowledged through replica B: the nurse on replica A hears of it.
                import httpx

                async with httpx.AsyncClient() as http:
                    response = await http.post(
                        f"{replica_b.http}/api/alarms/{raised['id']}/acknowledge",
                        headers={"Authorization": f"Bearer {nurse_token}"},
                    )
                assert response.status_code == 200, response.text
                acknowledged = await wait_for_alarm(
                    nurse_on_a, lambda a: a["state"] == "acknowledged"
                )
                return raised, acknowledged

        raised, acknowledged = asyncio.run(scenario())
        deadline = time.monotonic() + 10
        while [r.change.value for r in manager.received] != ["raised", "acknowledged"]:
            assert time.monotonic() < deadline, [r.change.value for r in manager.received]
            time.sleep(0.05)
    manager.close()
    assert raised["state"] == "open" and raised["robot_id"] == "robot-a"
    assert acknowledged["id"] == raised["id"] and acknowledged["acknowledged_by"] == "nurse"
    assert {r.alarm_id for r in manager.received} == {raised["id"]}


@pytest.mark.timeout(60)
def test_garbage_on_the_real_robot_socket_gets_a_close_code_and_others_keep_streaming(
    backend_env, robot, session_factory, tmp_path
):
    from backend.models import Robot
    from backend.security import hash_robot_token

    with transaction(session_factory) as session:
        session.add(Robot(id="robot-b", ward="ward-a", token_hash=hash_robot_token("tok-b")))
    garbage = [
        (os.urandom(2048), protocol.CLOSE_BAD_MESSAGE),
        (
            '{"type": "frames", "frames": [{"seq": 1, "ts": 1.0, "keypoints": [[1.0',
            protocol.CLOSE_BAD_MESSAGE,
        ),
        ("x" * (protocol.MAX_MESSAGE_BYTES + 10), protocol.CLOSE_TOO_LARGE),
        ("x" * (5 * 1024 * 1024), 1009),  # beyond the server's websocket frame limit
    ]

    async def scenario() -> list[int]:
        codes = []
        async with connect(f"{server.ws}/ws/robot", max_size=None) as good:
            await good.send(Hello(robot_id="robot-b", token="tok-b").model_dump_json())
            await good.recv()
            for seq, (payload, _) in enumerate(garbage):
                async with connect(f"{server.ws}/ws/robot", max_size=None) as bad:
                    await robot_hello(bad)
                    await bad.send(payload)
                    try:
                        await asyncio.wait_for(bad.recv(), 10)
                    except ConnectionClosed as closed:
                        codes.append(closed.rcvd.code if closed.rcvd else None)
                await good.send(FrameBatch(frames=[frame(seq)]).model_dump_json())
                assert json.loads(await good.recv()) == {"type": "ack", "seq": seq}
        return codes

    with BackendProcess(backend_env, log_path=tmp_path / "backend.log") as server:
        codes = asyncio.run(scenario())
        with session_factory() as session:
            stored = session.scalar(
                select(func.count()).select_from(Frame).where(Frame.robot_id == "robot-b")
            )
    assert codes == [code for _, code in garbage]
    assert stored == len(garbage)
