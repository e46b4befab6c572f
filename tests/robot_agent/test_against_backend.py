"""The robot agent against the real backend (uvicorn subprocess on loopback, test database):
kill -9 during a GENERATED fall -> local alarm while it is down; after the restart the agent
resends, the nurse gets the Emergency alarm, and every frame is stored exactly once."""

from __future__ import annotations

import asyncio
import json
import time

import pytest
from sqlalchemy import func, select
from websockets.asyncio.client import connect

from backend.db import transaction
from backend.models import Frame, Role, User
from backend.process import BackendProcess
from backend.security import create_access_token, hash_password
from robot_agent.client import Backoff, LocalAlarm, RobotClient
from robot_agent.outbox import Outbox
from robot_agent.pipeline import FramePipeline
from robot_agent.sources.simulator import _observations
from tests.robot_agent.conftest import ROBOT_TOKEN
from vigil.classes import Decision, TransportMode
from vigil.synthetic import generate_transport

SECRET = "robot-agent-secret"


@pytest.fixture
def backend_env(database_url, tmp_path) -> dict[str, str]:
    return {
        "VIGIL_DATABASE_URL": database_url,
        "VIGIL_SECRET_KEY": SECRET,
        "VIGIL_FRONTEND_DIR": str(tmp_path / "no-frontend"),
        "VIGIL_STREAM_STALL_SECONDS": "120",
        "VIGIL_ROBOT_OFFLINE_SECONDS": "120",
    }


@pytest.fixture
def nurse_token(session_factory) -> str:
    with transaction(session_factory) as session:
        user = User(username="nurse", password_hash=hash_password("nurse-password"),
                    role=Role.NURSE, ward="ward-a")  # fmt: skip
        session.add(user)
        session.flush()
        user_id = user.id
    return create_access_token(SECRET, user_id, 60)


def seq_counts(session_factory, robot_id: str) -> dict[int, int]:
    with session_factory() as session:
        rows = session.execute(
            select(Frame.seq, func.count()).where(Frame.robot_id == robot_id).group_by(Frame.seq)
        ).all()
    return dict(rows)


async def wait_for_alarm(ws, transport_id: str, timeout_s: float = 15) -> dict:
    deadline = time.monotonic() + timeout_s
    while True:
        remaining = deadline - time.monotonic()
        assert remaining > 0, "the alarm never reached the nurse"
        message = json.loads(await asyncio.wait_for(ws.recv(), remaining))
        alarms = message.get("alarms", []) + ([message["alarm"]] if "alarm" in message else [])
        for alarm in alarms:
            if alarm["kind"] == "emergency" and alarm["transport_id"] == transport_id:
                return alarm


@pytest.mark.timeout(120)
def test_backend_killed_during_a_fall_alarm_arrives_after_restart_nothing_lost(
    backend_env, robot, nurse_token, session_factory, tmp_path
):
    backend = BackendProcess(backend_env, log_path=tmp_path / "backend.log").start()
    transport = generate_transport("walking", seed=11, duration_s=14, events=["fall"])
    truth = transport.decisions()
    first_emergency = truth.index(Decision.EMERGENCY)
    outbox = Outbox(tmp_path / "outbox.sqlite")
    pipeline = FramePipeline(outbox, None, TransportMode.WALKING, use_ground_truth=True)
    client = RobotClient(backend.ws + "/ws/robot", robot, ROBOT_TOKEN, outbox, heartbeat_s=1,
                         backoff=Backoff(base_s=0.1, cap_s=0.5))  # fmt: skip
    hook_marker = tmp_path / "local-alarm"
    alarm = LocalAlarm(robot, hook_command=f"touch {hook_marker}", grace_s=0.3)
    facts: dict = {}

    async def scenario() -> dict:
        stop = asyncio.Event()
        client_task = asyncio.create_task(client.run(stop))
        for _ in range(100):
            if client.connected:
                break
            await asyncio.sleep(0.05)
        assert client.connected
        transport_id = pipeline.start_transport(TransportMode.WALKING, patient="P-7")
        client.notify()
        killed_at = None
        for i, obs in enumerate(_observations(transport)):
            result = pipeline.process(obs)
            client.notify()
            alarm.update(pipeline.emergency_holds, client.connected)
            if result and result.decision == Decision.EMERGENCY:
                facts.setdefault("first_emergency_seq", result.seq)
            if killed_at is None and i >= first_emergency + 5 and result is not None:
                await asyncio.sleep(0.3)  # let part of the fall reach the backend
                facts["acked_before_kill"] = client.acked_seq
                await asyncio.to_thread(backend.kill)
                killed_at = i
            if killed_at is not None and i == killed_at + 45:  # 1.5 s of frames later
                await asyncio.sleep(0.8)
                facts["local_alarm_while_down"] = alarm.raised
                facts["outbox_while_down"] = len(outbox)
                await asyncio.to_thread(backend.start)
            await asyncio.sleep(1 / 120)  # 4 x real time
        pipeline.end_transport()
        client.notify()
        async with connect(f"{backend.ws}/ws/browser?token={nurse_token}") as nurse:
            facts["alarm"] = await wait_for_alarm(nurse, transport_id)
        deadline = time.monotonic() + 20
        while len(outbox) and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        facts["left_in_outbox"] = len(outbox)
        facts["last_seq"] = outbox.next_seq - 1
        alarm.update(pipeline.emergency_holds, client.connected)
        facts["local_alarm_after"] = alarm.raised
        stop.set()
        await client_task
        return facts

    try:
        asyncio.run(scenario())
    finally:
        backend.stop()
        outbox.close()
    assert facts["acked_before_kill"] is not None
    assert facts["local_alarm_while_down"], "no local alarm while the backend was down"
    assert hook_marker.exists(), "the alarm hook command did not run"
    assert facts["outbox_while_down"] > 0
    assert client.connections >= 2  # reconnected after the restart
    assert facts["left_in_outbox"] == 0
    counts = seq_counts(session_factory, robot)
    assert sorted(counts) == list(range(facts["last_seq"] + 1)), "a frame was lost"
    assert set(counts.values()) == {1}, "a frame was stored twice"
    assert facts["alarm"]["state"] == "open" and facts["alarm"]["patient"] == "P-7"
    assert facts["alarm"]["first_seq"] == facts["first_emergency_seq"]
