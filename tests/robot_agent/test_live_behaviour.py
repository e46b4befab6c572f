"""The robot's behaviour end to end (issue #33): the agent process (console entry point) and
the real backend; the robot controller's view is the local UNIX socket."""

from __future__ import annotations

import json
import socket

import httpx

from tests.support.live_backend import ROBOT_ID

from .conftest import NurseSocket, wait_for
from .test_live_streaming import GENERATED_FALL
from .tiny_model import write_upright_model


def _lines(sock: socket.socket):
    buffer = b""
    while True:
        chunk = sock.recv(65536)
        if not chunk:
            return
        buffer += chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            yield json.loads(line)


def _connect(path, timeout=60) -> socket.socket:
    from .conftest import wait_for

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    wait_for(lambda: path.exists(), 30, "the agent's local socket")
    sock.connect(str(path))
    sock.settimeout(timeout)
    return sock


def _until(lines, predicate):
    for line in lines:
        if predicate(line):
            return line
    raise AssertionError("socket closed before the expected line")


def test_a_nurses_acknowledge_and_resolve_reach_the_robots_controller(backend, agents, tmp_path):
    model = write_upright_model(tmp_path / "model", "upright-1", threshold=0.5, delay_ms=200)
    path = tmp_path / "robot.sock"
    agent = agents(backend, *GENERATED_FALL, "--model-dir", str(model), "--local-socket", str(path))
    sock = _connect(path)
    lines = _lines(sock)
    try:
        assert next(lines)["state"] == "transporting"
        stop = _until(lines, lambda line: line["state"] == "emergency_stop")
        nurse = NurseSocket(backend)
        try:
            alarm = nurse.wait_alarm("emergency", ROBOT_ID, timeout=30)
        finally:
            nurse.close()
        assert stop["transport_id"] == alarm["transport_id"]
        headers = {"Authorization": f"Bearer {backend.login('nina')}"}
        url = f"{backend.base_url}/api/alarms/{alarm['id']}"
        assert httpx.post(f"{url}/acknowledge", headers=headers, timeout=10).status_code == 200
        ack = _until(lines, lambda line: line["event"] == "alarm_acknowledged")
        assert ack["state"] == "emergency_stop" and ack["alarm_id"] == alarm["id"]
        assert ack["acknowledged_by"] == "nurse:nina"
        resolved = httpx.post(
            f"{url}/resolve", headers=headers, json={"verdict": "true_emergency"}, timeout=10
        )
        assert resolved.status_code == 200, resolved.text
        released = _until(lines, lambda line: line["event"] == "behaviour")
        assert released["state"] == "transporting"
        assert f"alarm {alarm['id']} resolved by nurse:nina" in released["reason"]

        # What the robot did reaches the backend through the outbox: on the alarm (the board
        # shows it), in its audit, and on the fleet page.
        def robot_state():
            return httpx.get(url, headers=headers, timeout=10).json()["robot_state"]

        wait_for(lambda: robot_state() == "transporting", 30, "the robot's release on the alarm")
        audit = httpx.get(f"{url}/events", headers=headers, timeout=10).json()
        told = [e["comment"] for e in audit if e["action"] == "robot_behaviour"]
        assert told[0].startswith("robot stopped, waiting for help (emergency_stop) at ")
        assert told[-1].startswith("robot driving (transporting) at ")
    finally:
        sock.close()
    assert "behaviour: EMERGENCY_STOP" in agent.log()
    events = agent.hook_events()
    assert "behaviour robot-a" in events and "acknowledged robot-a" in events
