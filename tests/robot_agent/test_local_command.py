"""The local command output (robot_agent.local_command): behaviour changes reach the robot's
controller over a UNIX socket from the decision path, with the backend unreachable."""

from __future__ import annotations

import asyncio
import json
import socket
import sys
from concurrent.futures import ThreadPoolExecutor

from robot_agent import cli
from robot_agent.agent import AgentOptions, RobotAgent, TransportPlan
from robot_agent.controller_client import reset as client_reset
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.sources.simulator import SimulatorSource
from vigil.classes import Decision, TransportMode
from vigil.runtime import FrameClassifier

from .tiny_model import write_upright_model

HOOK = """import os, sys
with open(sys.argv[1], "a") as out:
    out.write(os.environ["VIGIL_ALARM_STATE"] + " " + os.environ["VIGIL_BEHAVIOUR_STATE"] + "\\n")
"""


def _unused_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _agent(tmp_path, hook: str | None = None) -> RobotAgent:
    model = write_upright_model(tmp_path / "m1", "upright-1", threshold=0.5, delay_ms=200)
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING, FrameClassifier.from_dir(model)
    )
    fall = SimulatorSource("walking", seed=3, duration_s=12, n_people=1, events=["fall"], speed=0)
    plan = TransportPlan(list(fall), patient="GEN-1")
    options = AgentOptions(
        # nothing listens there: the backend is unreachable for the whole test
        url=f"ws://127.0.0.1:{_unused_port()}/ws/robot",
        speed=0,
        backoff_initial_s=0.05,
        backoff_max_s=0.1,
        local_socket=tmp_path / "robot.sock",
        alarm_hook=hook,
    )
    return RobotAgent("robot-a", "token", pipeline, iter([plan]), options, tmp_path / "models")


async def _read_until(reader: asyncio.StreamReader, state: str, timeout: float = 30) -> list:
    seen = []
    async with asyncio.timeout(timeout):
        while True:
            line = json.loads(await reader.readline())
            seen.append(line)
            if line.get("state") == state:
                return seen


def test_a_fall_with_the_backend_unreachable_puts_emergency_stop_on_the_socket(tmp_path):
    hook = tmp_path / "hook.py"
    hook.write_text(HOOK)
    agent = _agent(tmp_path, f"{sys.executable} {hook} {tmp_path / 'hook.log'}")

    async def scenario():
        await agent.local.start()
        reader, writer = await asyncio.open_unix_connection(str(tmp_path / "robot.sock"))
        first = json.loads(await reader.readline())  # the current state on connecting
        assert first["state"] == "transporting"
        run = asyncio.create_task(agent.produce())
        lines = await _read_until(reader, "emergency_stop")
        await run  # the transport ends; the robot stays stopped
        await asyncio.sleep(0.5)  # the hook process
        writer.close()
        return lines

    with ThreadPoolExecutor(1) as pool:
        lines = pool.submit(asyncio.run, scenario()).result()
    stop = lines[-1]
    assert set(stop) >= {"state", "reason", "since", "transport_id", "alarm_id"}
    assert stop["transport_id"].startswith("robot-a-") and stop["alarm_id"] is None
    assert "Emergency" in stop["reason"]
    assert agent.outbox.oldest_unacked_emergency() is not None  # nothing reached a backend
    assert agent.behaviour.state == "emergency_stop"
    assert "behaviour emergency_stop" in (tmp_path / "hook.log").read_text().split("\n")


def test_reset_on_the_socket_releases_the_emergency_stop(tmp_path):
    agent = _agent(tmp_path)

    async def scenario():
        await agent.local.start()
        reader, writer = await asyncio.open_unix_connection(str(tmp_path / "robot.sock"))
        await reader.readline()
        await agent.produce()
        await _read_until(reader, "emergency_stop")
        # the reference client's reset, from a thread (it is blocking)
        reply = await asyncio.to_thread(client_reset, tmp_path / "robot.sock")
        after = await _read_until(reader, "transporting")
        again = await asyncio.to_thread(client_reset, tmp_path / "robot.sock")
        # `vigil-robot reset` on a robot that is not stopped: refused with the reason
        code = await asyncio.to_thread(
            cli.main, ["reset", "--local-socket", str(tmp_path / "robot.sock")]
        )
        writer.close()
        await agent.local.close()
        return reply, after[-1], again, code

    with ThreadPoolExecutor(1) as pool:
        reply, after, again, code = pool.submit(asyncio.run, scenario()).result()
    assert reply == {"reset": True, "state": "transporting"}
    assert "reset on the robot" in after["reason"]
    assert again["reset"] is False and "nothing to reset" in again["reason"]
    assert code == 1
    assert len(agent.behaviour.resets) == 1
    # queued for the backend (sent on reconnect)
    queued = [json.loads(m.text) for m in agent.outbox.pending(limit=100_000) if m.seq is None]
    (reset,) = [m for m in queued if m["type"] == "emergency_reset"]
    assert reset["by"] == "local socket" and reset["transport_id"].startswith("robot-a-")


def test_reset_cli_stops_the_robot_via_the_socket_and_names_a_missing_agent(tmp_path, capsys):
    agent = _agent(tmp_path)
    path = str(tmp_path / "robot.sock")
    assert cli.main(["reset", "--local-socket", path]) == 1
    assert "no agent answers" in capsys.readouterr().err
    assert cli.main(["reset"]) == 2
    assert "local_socket" in capsys.readouterr().err

    async def scenario():
        await agent.local.start()
        await agent.produce()
        code = await asyncio.to_thread(cli.main, ["reset", "--local-socket", path])
        await agent.local.close()
        return code

    with ThreadPoolExecutor(1) as pool:
        assert pool.submit(asyncio.run, scenario()).result() == 0
    assert "emergency stop reset" in capsys.readouterr().out
    assert agent.behaviour.state == "transporting"


def test_only_a_resolved_emergency_alarm_releases_the_stop(tmp_path):
    from vigil.protocol import alarm_acknowledged, alarm_resolved

    agent = _agent(tmp_path)
    seen = []
    agent.behaviour.listeners.append(seen.append)
    agent.behaviour.update(Decision.EMERGENCY, 1.0, transport_id="t-1")
    agent.on_alarm(alarm_acknowledged(5, "emergency", "t-1", "nurse:alice", 2.0))
    assert (seen[-1].event, seen[-1].alarm_id, seen[-1].state) == (
        "alarm_acknowledged",
        5,
        "emergency_stop",
    )
    agent.on_alarm(alarm_resolved(6, "pause", "t-1", "nurse:alice", 3.0))
    assert agent.behaviour.state == "emergency_stop"
    agent.on_alarm(alarm_resolved(5, "emergency", "t-1", "nurse:alice", 4.0, "true_emergency"))
    assert agent.behaviour.state == "transporting"
    assert seen[-1].reason == "alarm 5 resolved by nurse:alice on the board"
