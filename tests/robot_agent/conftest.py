"""Live fixtures: the real backend (uvicorn subprocess, throwaway migrated SQLite database) and
the agent started through its console entry point."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from websockets.sync.client import connect

from tests.support.live_backend import REPO_ROOT, ROBOT_ID, ROBOT_TOKEN, LiveServer

HOOK = """import os, sys
with open(sys.argv[1], "a") as out:
    out.write(os.environ["VIGIL_ALARM_STATE"] + " " + os.environ["VIGIL_ALARM_ROBOT"] + "\\n")
"""


@pytest.fixture
def backend(tmp_path) -> Iterator[LiveServer]:
    server = LiveServer.create(tmp_path, assignment_resend_s="3", monitor_interval_s="0.5")
    server.start()
    yield server
    server.stop()


def wait_for(condition, timeout: float, what: str, interval: float = 0.1):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(interval)
    raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")


def query(server: LiveServer, sql: str, *params) -> list[tuple]:
    path = server.database_url.removeprefix("sqlite:///")
    with sqlite3.connect(path, timeout=10) as db:
        return db.execute(sql, params).fetchall()


class AgentProcess:
    """`python -m robot_agent.cli run ...` for robot-a, its log in a file."""

    def __init__(
        self, workdir: Path, server: LiveServer, *args: str, backend_url: str | None = None
    ) -> None:
        self.log_path = workdir / "agent.log"
        self.outbox = workdir / "outbox.sqlite"
        self.hook_log = workdir / "hook.log"
        hook = workdir / "hook.py"
        hook.write_text(HOOK)
        command = [
            sys.executable,
            "-m",
            "robot_agent.cli",
            "run",
            "--backend",
            backend_url or server.robot_ws_url,
            "--robot-id",
            ROBOT_ID,
            "--token",
            ROBOT_TOKEN,
            "--outbox",
            str(self.outbox),
            "--models-dir",
            str(workdir / "robot-models"),
            "--heartbeat-s",
            "1",
            "--backoff-initial-s",
            "0.2",
            "--backoff-max-s",
            "1",
            "--alarm-hook",
            f"{sys.executable} {hook} {self.hook_log}",
            *args,
        ]
        self.process = subprocess.Popen(
            command,
            cwd=REPO_ROOT,
            stdout=subprocess.DEVNULL,
            stderr=self.log_path.open("w"),
        )

    def log(self) -> str:
        return self.log_path.read_text()

    def hook_events(self) -> list[str]:
        return self.hook_log.read_text().split("\n")[:-1] if self.hook_log.exists() else []

    def alarm_hook_events(self) -> list[str]:
        """The local alarm's hook calls (raised/cleared), not the behaviour changes'."""
        return [e for e in self.hook_events() if e.split()[0] in ("raised", "cleared")]

    def next_seq(self) -> int:
        with sqlite3.connect(self.outbox) as db:
            return db.execute("SELECT value FROM meta WHERE key = 'next_seq'").fetchone()[0]

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


@pytest.fixture
def agents(tmp_path):
    started: list[AgentProcess] = []

    def start(server: LiveServer, *args: str, backend_url: str | None = None) -> AgentProcess:
        agent = AgentProcess(tmp_path, server, *args, backend_url=backend_url)
        started.append(agent)
        return agent

    yield start
    for agent in started:
        agent.stop()


class NurseSocket:
    def __init__(self, server: LiveServer) -> None:
        token = server.login("nina")
        self.connection = connect(
            server.browser_ws_url,
            additional_headers={"Authorization": f"Bearer {token}"},
            open_timeout=10,
        )
        self.alarms: list[dict] = []

    def wait_alarm(self, kind: str, robot_id: str, timeout: float) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            for alarm in self.alarms:
                if alarm["kind"] == kind and alarm["robot_id"] == robot_id:
                    return alarm
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no {kind} alarm for {robot_id} at the nurse socket")
            message = json.loads(self.connection.recv(timeout=remaining))
            if message["type"] == "snapshot":
                self.alarms.extend(message["alarms"])
            elif message["type"] == "alarm":
                self.alarms.append(message["alarm"])

    def close(self) -> None:
        self.connection.close()
