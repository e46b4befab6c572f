"""A real MLLP Alert Manager in the test process (the demo's simulator, on its own event loop in a
thread), and a backend that sends it every alarm change and listens for its dispositions."""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections.abc import Callable, Iterator

import pytest
from fastapi.testclient import TestClient

from backend.main import create_app
from backend.models.users import Role, User
from backend.security import create_access_token
from backend.settings import Settings
from backend.unit_of_work import transaction
from scripts.alert_manager_simulator import AlertManagerSimulator
from tests.backend.conftest import PASSWORD, ROBOT_TOKEN, Account
from tests.support.live_backend import free_port
from tests.support.passwords import password_hash
from vigil.protocol import FrameBatch, FrameRecord, Hello, TransportStart


class ThreadedAlertManager:
    """The simulator served from a thread, so the TestClient's backend (another thread, its own
    loop) talks to it over real sockets."""

    def __init__(self, port: int, **options) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.shown: list[str] = []
        self.simulator = AlertManagerSimulator(port=port, show=self.shown.append, **options)
        self.running = False

    def run(self, coroutine):
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(10)

    def start(self) -> None:
        self.run(self.simulator.start())
        self.running = True

    def stop(self) -> None:
        if self.running:
            self.run(self.simulator.stop())
            self.running = False

    def close(self) -> None:
        self.stop()
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()

    @property
    def received(self):
        return list(self.simulator.received)


def wait_for(condition: Callable[[], object], timeout: float = 10.0, what: str = "condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


@pytest.fixture
def alert_manager_port() -> int:
    return free_port()


@pytest.fixture
def status_port() -> int:
    return free_port()


@pytest.fixture
def distribution_settings(settings: Settings, alert_manager_port: int, status_port: int):
    return settings.model_copy(
        update={
            "alert_manager": f"127.0.0.1:{alert_manager_port}",
            "alert_status_listen": f"127.0.0.1:{status_port}",
            "alert_facility": "ST-ELSEWHERE",
            "alert_ack_timeout_s": 0.5,
            "alert_retry_s": 0.2,
            "alarm_distribution_down_s": 0.6,
        }
    )


@pytest.fixture
def make_alert_manager(alert_manager_port: int, status_port: int):
    from backend.distribution.routing import Destination

    made: list[ThreadedAlertManager] = []

    def make(start: bool = True, **options) -> ThreadedAlertManager:
        options.setdefault("vigil", Destination("127.0.0.1", status_port))
        manager = ThreadedAlertManager(alert_manager_port, **options)
        if start:
            manager.start()
        made.append(manager)
        return manager

    yield make
    for manager in made:
        manager.close()


@pytest.fixture
def nurse(settings: Settings, session_factory) -> Account:
    """A ward-a nurse, made without starting a second backend (whose alarm monitor would race
    this one's on the same database)."""
    with transaction(session_factory) as session:
        user = User(
            username="alice", password_hash=password_hash(PASSWORD), role=Role.NURSE, ward="ward-a"
        )
        session.add(user)
        session.flush()
        token = create_access_token(settings.secret_key, user.id, 60)
    return Account("alice", Role.NURSE, "ward-a", token)


@pytest.fixture
def distributing_client(distribution_settings: Settings) -> Iterator[TestClient]:
    with TestClient(create_app(distribution_settings)) as test_client:
        yield test_client


def emergency_frames(first_seq: int = 0, transport: str = "t-1") -> FrameBatch:
    def frame(seq: int, decision: str) -> FrameRecord:
        return FrameRecord(
            seq=seq,
            ts=time.time(),
            transport_id=transport,
            keypoints=[[100.0 + i, 200.0 + i, 0.9] for i in range(25)],
            depth=[2.0] * 24 + [None],
            floor=[1.5, 0.75, None],
            decision=decision,
            scores={"normal": 0.1, "emergency": 0.9}
            if decision == "emergency"
            else {"normal": 0.9},
            model_version="m-1",
            threshold=0.4,
            delay_ms=120,
        )

    return FrameBatch(
        frames=[frame(first_seq, "normal"), frame(first_seq + 1, "emergency")],
    )


def stream_an_emergency(client: TestClient, robot: str, transport: str = "t-1") -> None:
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text())["type"] == "welcome"
        ws.send_text(
            TransportStart(
                transport_id=transport, mode="walking", patient="P-17", location="corridor B", ts=0
            ).model_dump_json()
        )
        ws.send_text(emergency_frames(transport=transport).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 1}
