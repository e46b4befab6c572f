"""A commit's alarms go out together (`AlarmBus.publish_many`): every browser allowed to see
them gets them in their order, on this replica and, through Redis, on the others; a browser
whose socket fails is dropped and the others still get everything."""

from __future__ import annotations

import asyncio
import json
import uuid
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from backend.models import Role
from backend.realtime.bus import AlarmBus
from backend.realtime.hub import BrowserConnection, BrowserHub
from tests.backend.test_reliability import REDIS_URL


class Socket:
    def __init__(self, fail: bool = False) -> None:
        self.sent: list[dict] = []
        self.fail = fail

    async def send_text(self, text: str) -> None:
        if self.fail:
            raise ConnectionResetError("browser went away")
        self.sent.append(json.loads(text))


@asynccontextmanager
async def replicas(*hubs: BrowserHub) -> AsyncIterator[list[AlarmBus]]:
    """One bus per hub on a fresh channel of the real Redis, started and stopped."""
    channel = f"vigil-test-{uuid.uuid4().hex}"
    buses = [AlarmBus(hub, REDIS_URL, channel) for hub in hubs]
    for bus in buses:
        await bus.start()
    try:
        yield buses
    finally:
        for bus in buses:
            await bus.stop()


def alarm(i: int, ward: str) -> dict:
    return {"id": i, "robot_id": f"robot-{i}", "ward": ward, "kind": "emergency"}


def ids(socket: Socket) -> list[int]:
    return [m["alarm"]["id"] for m in socket.sent if m["type"] == "alarm"]


def test_a_commit_s_alarms_reach_every_allowed_browser_in_order_on_every_replica():
    alarms = [alarm(i, "ward-a" if i % 3 else "ward-b") for i in range(60)]
    ward_a = [a["id"] for a in alarms if a["ward"] == "ward-a"]
    every = [a["id"] for a in alarms]

    async def scenario() -> dict[str, Socket]:
        hub_a, hub_b = BrowserHub(), BrowserHub()
        sockets = {
            "nurse_a": Socket(),
            "engineer_a": Socket(),
            "broken_a": Socket(fail=True),
            "nurse_b": Socket(),
            "engineer_b": Socket(),
        }
        hub_a.add(BrowserConnection(sockets["nurse_a"], 1, Role.NURSE, "ward-a"))
        hub_a.add(BrowserConnection(sockets["engineer_a"], 2, Role.ENGINEER, None))
        hub_a.add(BrowserConnection(sockets["broken_a"], 3, Role.ENGINEER, None))
        hub_b.add(BrowserConnection(sockets["nurse_b"], 4, Role.NURSE, "ward-a"))
        hub_b.add(BrowserConnection(sockets["engineer_b"], 5, Role.ENGINEER, None))
        async with replicas(hub_a, hub_b) as (bus_a, _):
            await bus_a.publish_many(alarms[:30])
            await bus_a.publish_many(alarms[30:])
            for _ in range(300):
                if len(ids(sockets["engineer_b"])) >= len(alarms):
                    break
                await asyncio.sleep(0.01)
            await asyncio.sleep(0.1)  # replica A ignores its own messages: no second copy
        assert hub_a.size == 2  # the broken browser was dropped
        return sockets

    sockets = asyncio.run(scenario())
    assert ids(sockets["nurse_a"]) == ids(sockets["nurse_b"]) == ward_a
    assert ids(sockets["engineer_a"]) == ids(sockets["engineer_b"]) == every
    assert sockets["broken_a"].sent == []
