"""The agent against the real backend on loopback: a backend killed with SIGKILL during a fall
loses nothing, the robot raises its local alarm meanwhile, and the nurse gets the alarm after
the restart."""

from __future__ import annotations

import pytest

from tests.support.live_backend import ROBOT_ID

from .conftest import NurseSocket, query, wait_for
from .tiny_model import write_upright_model

GENERATED_FALL = [
    "--source",
    "generated",
    "--scenario",
    "fall",
    "--seed",
    "3",
    "--people",
    "1",
    "--duration-s",
    "12",
    "--speed",
    "2",
]


def frames_by_seq(backend) -> tuple[int, int, int | None, int | None]:
    (row,) = query(
        backend,
        "SELECT COUNT(*), COUNT(DISTINCT seq), MIN(seq), MAX(seq) FROM frames WHERE robot_id = ?",
        ROBOT_ID,
    )
    return row


def emergency_alarms(backend) -> list[tuple]:
    return query(
        backend,
        "SELECT id, first_seq FROM alarms WHERE robot_id = ? AND kind = ?",
        ROBOT_ID,
        "emergency",
    )


def test_backend_killed_during_a_fall_loses_no_frame_and_the_alarm_arrives_after_restart(
    backend, agents, tmp_path
):
    model = write_upright_model(tmp_path / "model", "upright-1", threshold=0.5, delay_ms=200)
    agent = agents(
        backend,
        *GENERATED_FALL,
        "--model-dir",
        str(model),
        "--alarm-after-s",
        "1",
        "--exit-when-done",
    )
    wait_for(lambda: frames_by_seq(backend)[0] >= 30, 30, "the first frames to be stored")
    assert emergency_alarms(backend) == []  # the patient is still walking
    backend.kill()

    # The patient falls while the backend is dead: the robot alarms locally.
    wait_for(lambda: "raised robot-a" in agent.alarm_hook_events(), 30, "the local alarm hook")
    assert "LOCAL ALARM robot robot-a" in agent.log()
    backend.start()
    nurse = NurseSocket(backend)
    try:
        alarm = nurse.wait_alarm("emergency", ROBOT_ID, timeout=30)
    finally:
        nurse.close()
    assert alarm["state"] == "open"

    assert agent.process.wait(60) == 0, agent.log()[-3000:]
    sent = agent.next_seq()
    count, distinct, first, last = frames_by_seq(backend)
    assert (count, distinct, first, last) == (sent, sent, 0, sent - 1)
    assert sent >= 12 * 30 * 0.9  # the whole generated transport
    assert agent.alarm_hook_events() == ["raised robot-a", "cleared robot-a"]
    (first_emergency,) = [seq for _, seq in emergency_alarms(backend)]
    decisions = query(
        backend,
        "SELECT decision, model_version, threshold, delay_ms FROM frames "
        "WHERE robot_id = ? AND seq = ?",
        ROBOT_ID,
        first_emergency,
    )
    assert decisions == [("emergency", "upright-1", 0.5, 200)]


def test_agent_with_a_fresh_outbox_continues_after_the_backends_numbers(backend, agents, tmp_path):
    """A re-installed robot (new outbox file) must not have its new frames taken for
    duplicates of the old ones."""
    query(backend, "UPDATE robots SET last_seq = 500 WHERE id = ?", ROBOT_ID)
    model = write_upright_model(tmp_path / "model", "upright-1")
    agent = agents(
        backend,
        *GENERATED_FALL[:-1],
        "8",
        "--duration-s",
        "4",
        "--model-dir",
        str(model),
        "--exit-when-done",
    )
    assert agent.process.wait(60) == 0, agent.log()[-3000:]
    count, distinct, first, last = frames_by_seq(backend)
    assert first == 501 and count == distinct == last - 500 == agent.next_seq() - 501


@pytest.mark.parametrize("token", ["wrong-token"])
def test_a_refused_token_stops_the_agent_with_a_clear_message(backend, tmp_path, token):
    import subprocess
    import sys

    from tests.support.live_backend import REPO_ROOT

    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "robot_agent.cli",
            "run",
            "--backend",
            backend.robot_ws_url,
            "--robot-id",
            ROBOT_ID,
            "--token",
            token,
            "--outbox",
            str(tmp_path / "o.sqlite"),
            "--duration-s",
            "2",
            "--people",
            "1",
        ],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    assert "refused this robot's id or token" in result.stderr
