"""The real backend for tests and benchmarks: uvicorn as a subprocess on a free port against a
throwaway, migrated SQLite database (a nurse, an annotator and robot-a in ward-a seeded).

`kill()` ends it with SIGKILL (no shutdown, nothing flushed) and `start()` brings it back on the
same port and database."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import httpx

from backend.db import make_engine, make_session_factory, transaction
from backend.migrate import upgrade
from backend.models import Robot, Role, User
from backend.security import hash_robot_token
from tests.support.passwords import password_hash as cached_password_hash

REPO_ROOT = Path(__file__).resolve().parents[2]
PASSWORD = "nurse-password-1"
ROBOT_ID = "robot-a"
ROBOT_TOKEN = "browser-test-robot-token"
#: Generous: a start-up costs ~3 s of CPU, and on a loaded 2-core machine (two test runs side by
#: side, at low priority) it has taken over 30 s of wall time.
STARTUP_TIMEOUT_S = 120


def prepare_database(database_url: str) -> None:
    """Migrate, then add nurse 'nina' (ward-a), annotator 'anna' and robot-a (ward-a)."""
    upgrade(database_url)
    engine = make_engine(database_url)
    with transaction(make_session_factory(engine)) as session:
        password_hash = cached_password_hash(PASSWORD)
        session.add(
            User(username="nina", password_hash=password_hash, role=Role.NURSE, ward="ward-a")
        )
        session.add(User(username="anna", password_hash=password_hash, role=Role.ANNOTATOR))
        session.add(
            Robot(id=ROBOT_ID, name="A", ward="ward-a", token_hash=hash_robot_token(ROBOT_TOKEN))
        )
    engine.dispose()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class LiveServer:
    base_url: str
    database_url: str
    port: int
    env: dict[str, str]
    log_path: Path
    process: subprocess.Popen | None = None

    @classmethod
    def create(
        cls, workdir: Path, frontend_dist: Path | None = None, **settings: str
    ) -> LiveServer:
        """settings: extra backend settings, e.g. assignment_resend_s="1" (VIGIL_* variables)."""
        database_url = f"sqlite:///{workdir / 'vigil.db'}"
        prepare_database(database_url)
        port = free_port()
        env = {
            **os.environ,
            "VIGIL_DATABASE_URL": database_url,
            "VIGIL_FRONTEND_DIR": str(frontend_dist or workdir / "no-frontend"),
            "VIGIL_SECRET_KEY": "browser-test-secret",
            **{f"VIGIL_{k.upper()}": v for k, v in settings.items()},
        }
        env.pop("VIGIL_REDIS_URL", None)
        return cls(f"http://127.0.0.1:{port}", database_url, port, env, workdir / "backend.log")

    def replica(self, name: str) -> LiveServer:
        """Another backend process on the same database (its own port and log)."""
        port = free_port()
        env = {**self.env, "VIGIL_REPLICA_NAME": name}
        log_path = self.log_path.with_name(f"backend-{name}.log")
        return LiveServer(f"http://127.0.0.1:{port}", self.database_url, port, env, log_path)

    def duties(self) -> dict:
        """/api/health's duties: whether this replica runs the alarm monitor and distribution."""
        return httpx.get(f"{self.base_url}/api/health", timeout=5).json()["duties"]

    @property
    def robot_ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/robot"

    @property
    def browser_ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/browser"

    def start(self) -> None:
        log = self.log_path.open("ab")
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "uvicorn",
                "backend.main:create_app",
                "--factory",
                "--host",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--log-level",
                "warning",
            ],
            cwd=REPO_ROOT,
            env=self.env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"backend exited: {self.log_path.read_text()[-2000:]}")
            try:
                if httpx.get(f"{self.base_url}/api/health", timeout=1).status_code == 200:
                    return
            except httpx.HTTPError:
                time.sleep(0.1)
        self.stop()  # no server left running behind a failed test
        raise RuntimeError(f"backend did not come up in {STARTUP_TIMEOUT_S} s")

    def kill(self) -> None:
        """SIGKILL: the process dies at once, as in a power cut of the server."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGKILL)
            self.process.wait()
        self.process = None

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None

    def login(self, username: str = "nina", password: str = PASSWORD) -> str:
        """A user's bearer token."""
        credentials = {"username": username, "password": password}
        response = httpx.post(f"{self.base_url}/api/auth/login", json=credentials, timeout=10)
        response.raise_for_status()
        return response.json()["access_token"]
