"""The robot reports the sha256 of the model file it runs (hello, heartbeat); the welcome answers
with the registry's sha256 of the versions it named; the fleet is in sync only when the robot's
target version runs from the registry's file (issue 18, item 5)."""

from __future__ import annotations

import json
import time

import pytest

from backend.db import transaction
from backend.models import Robot, Role
from backend.models.registry import ModelVersion
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_first_alarm import frame
from tests.robot_agent.tiny_model import write_upright_model
from vigil.model_file import read_manifest
from vigil.protocol import FrameBatch, Heartbeat, Hello

TAMPERED = "ab" * 32


@pytest.fixture
def registered(session_factory, robot, tmp_path) -> tuple[str, str]:
    """upright-7 in the registry, assigned to robot-a; (version, the registry's sha256)."""
    manifest, directory = read_manifest(write_upright_model(tmp_path / "m", "upright-7"))
    with transaction(session_factory) as session:
        model = ModelVersion(
            version=manifest.version,
            mode=manifest.mode,
            kind="test",
            file_path=str(directory / manifest.file),
            sha256=manifest.sha256,
            manifest=manifest.model_dump(mode="json"),
        )
        session.add(model)
        session.flush()
        session.get(Robot, robot).assigned_model_id = model.id
    return manifest.version, manifest.sha256


def receive_until(ws, kind: str) -> list[dict]:
    messages = []
    while not messages or messages[-1]["type"] != kind:
        messages.append(json.loads(ws.receive_text()))
    return messages


def fleet_row(client, headers, reported: str | None = None) -> dict:
    """robot-a's fleet row; `reported`: the running version its hello gave, which the frame
    writer stores just after the welcome (the welcome never waits on storage): waited for."""
    deadline = time.monotonic() + 5
    while True:
        rows = client.get("/api/fleet", headers=headers).json()
        row = next(r for r in rows if r["id"] == "robot-a")
        if reported is None or row["running_version"] == reported or time.monotonic() > deadline:
            return row
        time.sleep(0.02)


def test_a_robot_running_another_file_under_the_target_version_is_not_in_sync(
    client, make_account, registered
):
    version, registry_sha = registered
    engineer = make_account(Role.ENGINEER)
    with client.websocket_connect("/ws/robot") as ws:
        hello = Hello(
            robot_id="robot-a",
            token=ROBOT_TOKEN,
            running_model=version,
            running_sha256=TAMPERED,
            fallback_model="not-registered",
            fallback_sha256="cd" * 32,
        )
        ws.send_text(hello.model_dump_json(exclude_none=True))
        welcome = json.loads(ws.receive_text())
        assert welcome["type"] == "welcome"
        assert welcome["model_sha256"] == {version: registry_sha}  # what the registry knows
        # Not running the registry's file: the assignment is sent again, to fetch it anew.
        assignment = json.loads(ws.receive_text())
        assert assignment["type"] == "assign_model" and assignment["sha256"] == registry_sha
        row = fleet_row(client, engineer.headers, reported=version)
        assert (row["running_version"], row["running_sha256"]) == (version, TAMPERED)
        assert row["target_version"] == version and row["in_sync"] is False

        # The robot now runs the registry's file (heartbeat), and the fleet says so.
        ws.send_text(
            Heartbeat(ts=1.0, running_model=version, running_sha256=registry_sha).model_dump_json()
        )
        ws.send_text(FrameBatch(frames=[frame(0)]).model_dump_json())
        receive_until(ws, "ack")  # committed after the heartbeat
        row = fleet_row(client, engineer.headers)
        assert row["running_sha256"] == registry_sha and row["in_sync"] is True


def test_an_agent_that_reports_no_sha256_gets_the_old_welcome_and_is_not_shown_in_sync(
    client, make_account, registered
):
    version, _ = registered
    engineer = make_account(Role.ENGINEER)
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(
            Hello(robot_id="robot-a", token=ROBOT_TOKEN, running_model=version).model_dump_json(
                exclude_none=True
            )
        )
        welcome = json.loads(ws.receive_text())
        assert welcome["type"] == "welcome" and "model_sha256" not in welcome
        row = fleet_row(client, engineer.headers, reported=version)
        assert row["running_version"] == version and row["running_sha256"] is None
        assert row["in_sync"] is False  # its file cannot be shown to be the registry's
