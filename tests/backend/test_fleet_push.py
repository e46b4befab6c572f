"""The fleet's news is pushed, not polled (issue 35): when a robot says hello, reports another
running model, a behaviour or degraded detection, or goes offline, and when a rollout changes,
the backend tells the browsers that may see the fleet (engineers, admins) on /ws/browser, once
the change is committed, so the fleet page reloads at once instead of showing "switching…"
until its next poll."""

from __future__ import annotations

import asyncio
import json
import time

import pytest

from backend.models import Robot, Role
from backend.realtime.hub import BrowserConnection, BrowserHub
from backend.unit_of_work import UnitOfWork, fleet_changed, unit_of_work
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.realtime.test_bus import replicas
from tests.backend.test_first_alarm import frame
from tests.backend.test_robot_model_sha import registered  # noqa: F401
from vigil.protocol import (
    BehaviourChanged,
    DetectionStatus,
    FrameBatch,
    Heartbeat,
    Hello,
    TransportStart,
)

OTHER_SHA = "ab" * 32


class Recorder:
    def __init__(self) -> None:
        self.fleet: list[list[str]] = []

    async def publish_alarm(self, alarm: dict) -> None:
        pass

    async def push_assignments(self, robot_ids: list[str]) -> None:
        pass

    async def publish_fleet(self, robot_ids: list[str]) -> None:
        self.fleet.append(robot_ids)


def test_fleet_news_goes_out_after_the_commit_and_never_after_a_rollback(session_factory):
    effects = Recorder()
    with unit_of_work(session_factory) as unit:
        unit.session.add(Robot(id="robot-u", name="", ward="ward-a"))
        fleet_changed(unit.session, ["robot-u", "robot-u"])
        fleet_changed(unit.session)  # a deployment changed: news even without a robot
        asyncio.run(unit.run_after_commit(effects))  # not committed yet: nothing runs
        assert effects.fleet == []
    with pytest.raises(RuntimeError), unit_of_work(session_factory) as failed:
        fleet_changed(failed.session, ["robot-v"])
        raise RuntimeError("refused")
    asyncio.run(failed.run_after_commit(effects))
    asyncio.run(unit.run_after_commit(effects))
    asyncio.run(unit.run_after_commit(effects))  # once only
    assert effects.fleet == [["robot-u"]]

    quiet = UnitOfWork(session_factory)  # a unit that changed no fleet says nothing
    quiet.commit()
    quiet.close()
    asyncio.run(quiet.run_after_commit(effects))
    assert effects.fleet == [["robot-u"]]


class FakeSocket:
    def __init__(self) -> None:
        self.sent: list[dict] = []

    async def send_text(self, text: str) -> None:
        self.sent.append(json.loads(text))


def test_only_those_who_may_see_the_fleet_are_told():
    hub = BrowserHub()
    sockets = {role: FakeSocket() for role in (Role.NURSE, Role.ENGINEER, Role.ADMIN)}
    for i, (role, socket) in enumerate(sockets.items()):
        hub.add(BrowserConnection(socket, i, role, "ward-a" if role == Role.NURSE else None))
    asyncio.run(hub.publish_fleet(["robot-b", "robot-a"]))
    told = {role: socket.sent for role, socket in sockets.items()}
    fleet = [{"type": "fleet", "robots": ["robot-a", "robot-b"]}]
    assert told == {Role.NURSE: [], Role.ENGINEER: fleet, Role.ADMIN: fleet}


def news(browser) -> dict:
    """The browser socket's next message that is not an alarm (the alarm monitor may raise a
    stalled stream meanwhile: alarms are not what this is about)."""
    while (message := browser.receive_json())["type"] == "alarm":
        pass
    return message


def told(browser) -> list[dict]:
    """What the browser was told so far (but alarms): the messages before the pong to a ping
    sent now (the hub sends a connection's messages in order)."""
    browser.send_text("ping")
    messages = []
    while (message := news(browser)) != {"type": "pong"}:
        messages.append(message)
    return messages


FLEET_NEWS = [{"type": "fleet", "robots": ["robot-a"]}]


@pytest.mark.timeout(60)
def test_a_robot_s_hello_new_model_and_disconnect_reach_the_engineer_only(
    client,
    make_account,
    registered,  # noqa: F811
):
    version, registry_sha = registered
    engineer = make_account(Role.ENGINEER, ward=None)
    nurse = make_account(Role.NURSE, ward="ward-a")
    with (
        client.websocket_connect("/ws/browser", headers=engineer.headers) as engineer_ws,
        client.websocket_connect("/ws/browser", headers=nurse.headers) as nurse_ws,
    ):
        assert engineer_ws.receive_json()["type"] == "snapshot"
        assert nurse_ws.receive_json()["type"] == "snapshot"
        with client.websocket_connect("/ws/robot") as robot:

            def then_frames(seq: int) -> None:
                """Frames whose ack says the flush before committed and its effects ran (the
                writer runs them before it acknowledges)."""
                robot.send_text(FrameBatch(frames=[frame(seq)]).model_dump_json())
                while json.loads(robot.receive_text()) != {"type": "ack", "seq": seq}:
                    pass

            def heartbeat(seq: int, sha256: str | None) -> None:
                beat = Heartbeat(ts=0.0, running_model=version, running_sha256=sha256)
                robot.send_text(beat.model_dump_json(exclude_none=True))
                then_frames(seq)

            hello = Hello(robot_id="robot-a", token=ROBOT_TOKEN, running_model="old-1")
            robot.send_text(hello.model_dump_json(exclude_none=True))
            start = TransportStart(
                transport_id="t-1", mode="walking", patient="P-1", location="ward", ts=0.0
            )
            robot.send_text(start.model_dump_json())
            then_frames(0)
            # The hello (stored by the frame writer after the welcome): news once committed.
            assert told(engineer_ws) == FLEET_NEWS
            # The robot switched to its target model: news.
            heartbeat(1, registry_sha)
            assert told(engineer_ws) == FLEET_NEWS
            # The same model again (a heartbeat every 5 s): no news.
            heartbeat(2, registry_sha)
            assert told(engineer_ws) == []
            # Another file under the same version: news (the row is no longer in sync).
            heartbeat(3, OTHER_SHA)
            assert told(engineer_ws) == FLEET_NEWS
            # What the robot does and whether its detection is degraded are on the row too.
            now = time.time()
            changed = BehaviourChanged(ts=now, since=now, state="paused", transport_id="t-1")
            robot.send_text(changed.model_dump_json(exclude_none=True))
            then_frames(4)
            assert told(engineer_ws) == FLEET_NEWS
            status = DetectionStatus(
                ts=now, transport_id="t-1", degraded=True, missing_inputs=["depth"]
            )
            robot.send_text(status.model_dump_json(exclude_none=True))
            then_frames(5)
            assert told(engineer_ws) == FLEET_NEWS
            robot.send_text(status.model_dump_json(exclude_none=True))  # a replay: no change
            then_frames(6)
            assert told(engineer_ws) == []
            # Offline: the row says so at once. (Closed here: leaving the block would also
            # cancel the server's side of the socket, as a server shutting down does.)
            robot.close(1000)
            assert news(engineer_ws) == FLEET_NEWS[0]

        # The nurse (no fleet page) heard none of it.
        assert told(nurse_ws) == []


def test_the_fleet_s_news_crosses_replicas_through_redis():

    async def scenario() -> tuple[list[dict], list[dict]]:
        hub_a, hub_b = BrowserHub(), BrowserHub()
        socket_a, socket_b = FakeSocket(), FakeSocket()
        hub_a.add(BrowserConnection(socket_a, 1, Role.ENGINEER, None))
        hub_b.add(BrowserConnection(socket_b, 2, Role.ENGINEER, None))
        async with replicas(hub_a, hub_b) as (bus_a, _):
            await bus_a.publish_fleet(["robot-a"])
            for _ in range(200):
                if socket_b.sent:
                    break
                await asyncio.sleep(0.01)
            await asyncio.sleep(0.1)  # replica A ignores its own message: still one push
        return socket_a.sent, socket_b.sent

    on_a, on_b = asyncio.run(scenario())
    assert on_a == on_b == [{"type": "fleet", "robots": ["robot-a"]}]


def test_a_reconnect_storm_s_news_goes_out_in_a_few_messages_with_every_robot_and_all_alarms():
    """A thousand robots saying hello at once (the replica left after a kill -9): the fleet's
    news leaves in a few messages that name every robot, and the alarms published at the same
    time all cross to the other replica (redis-py's pool used to refuse past 100 at once)."""

    async def scenario() -> tuple[list[dict], list[dict], list[dict]]:
        hub_a, hub_b = BrowserHub(), BrowserHub()
        socket_a, socket_b = FakeSocket(), FakeSocket()
        hub_a.add(BrowserConnection(socket_a, 1, Role.ENGINEER, None))
        hub_b.add(BrowserConnection(socket_b, 2, Role.ADMIN, None))
        alarms = [
            {
                "id": i,
                "robot_id": f"robot-{i}",
                "ward": "ward-a",
                "kind": "emergency",
                "state": "open",
            }
            for i in range(300)
        ]
        async with replicas(hub_a, hub_b) as (bus_a, _):
            await asyncio.gather(
                *(bus_a.publish_fleet([f"robot-{i}"]) for i in range(1000)),
                *(bus_a.publish(alarm) for alarm in alarms),
            )
            for _ in range(300):
                fleet_b = [m for m in socket_b.sent if m["type"] == "fleet"]
                if sum(len(m["robots"]) for m in fleet_b) >= 1000 and len(socket_b.sent) > 300:
                    break
                await asyncio.sleep(0.01)
        return socket_a.sent, socket_b.sent, alarms

    on_a, on_b, alarms = asyncio.run(scenario())
    everyone = {f"robot-{i}" for i in range(1000)}
    for sent in (on_a, on_b):
        fleet = [m for m in sent if m["type"] == "fleet"]
        assert 1 <= len(fleet) <= 10
        assert set().union(*(m["robots"] for m in fleet)) == everyone
    assert sorted(m["alarm"]["id"] for m in on_b if m["type"] == "alarm") == list(range(300))
