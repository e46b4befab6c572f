"""The replicas' waiting robots through the real Redis (`SharedWaiting`): each replica sees the
others' and not its own, a stopped replica's go at once, a killed one's when its key expires,
and without Redis (or with Redis gone) a replica sees none and does not fail."""

from __future__ import annotations

import asyncio
import uuid

import redis.asyncio as redis

from backend.ingest.waiting import READ_TIMEOUT_S, SharedWaiting
from tests.backend.test_reliability import REDIS_URL


def shared(client, prefix: str, replica: str, robots: set[str], **timing) -> SharedWaiting:
    return SharedWaiting(lambda: frozenset(robots), client, prefix, replica, **timing)


def test_each_replica_sees_the_robots_waiting_in_the_others_writers():
    async def scenario():
        client = redis.Redis.from_url(REDIS_URL)
        prefix = f"vigil-test-{uuid.uuid4().hex}.waiting."
        waiting_a, waiting_b = {"robot-1"}, {"robot-2", "robot-3"}
        a = shared(client, prefix, "a", waiting_a)
        b = shared(client, prefix, "b", waiting_b, publish_s=0.05)
        c = shared(client, prefix, "c", set())
        for replica in (a, b, c):
            replica.start()
        await asyncio.sleep(0.2)
        seen = {"a": await a.elsewhere(), "b": await b.elsewhere(), "c": await c.elsewhere()}
        waiting_b.discard("robot-2")  # committed on b: gone by its next publish
        await asyncio.sleep(0.2)
        seen["a later"] = await a.elsewhere()
        await b.stop()  # a replica shut down takes its robots away at once
        seen["a after b stopped"] = await a.elsewhere()
        await a.stop()
        await c.stop()
        await client.aclose()
        return seen

    seen = asyncio.run(scenario())
    assert seen["a"] == {"robot-2", "robot-3"}
    assert seen["b"] == {"robot-1"}
    assert seen["c"] == {"robot-1", "robot-2", "robot-3"}
    assert seen["a later"] == {"robot-3"}
    assert seen["a after b stopped"] == set()


def test_a_killed_replica_s_waiting_robots_expire():
    async def scenario():
        client = redis.Redis.from_url(REDIS_URL)
        prefix = f"vigil-test-{uuid.uuid4().hex}.waiting."
        killed = shared(client, prefix, "killed", {"robot-1"}, ttl_s=0.3)
        await killed.publish()  # and then nothing more: no stop, no delete
        survivor = shared(client, prefix, "survivor", set())
        before = await survivor.elsewhere()
        await asyncio.sleep(0.5)
        after = await survivor.elsewhere()
        members = await client.smembers(f"{prefix}replicas")
        await client.aclose()
        return before, after, members

    before, after, members = asyncio.run(scenario())
    assert before == {"robot-1"}
    assert after == set()
    assert members == set()  # the expired replica left the set of replicas


def test_without_redis_or_with_redis_gone_a_replica_sees_none_and_keeps_going(caplog):
    async def scenario():
        alone = shared(None, "p.", "alone", {"robot-1"})
        alone.start()
        gone_client = redis.Redis(host="127.0.0.1", port=1, socket_connect_timeout=0.2)
        gone = shared(gone_client, "p.", "gone", {"robot-1"})
        await gone.publish()
        await gone.publish()
        result = (await alone.elsewhere(), await gone.elsewhere())
        await alone.stop()
        await gone_client.aclose()
        return result

    alone, gone = asyncio.run(scenario())
    assert alone == set() and gone == set()
    warnings = [r.getMessage() for r in caplog.records if "waiting robots" in r.getMessage()]
    # One warning when Redis went away, not one per publish or read of the same outage.
    assert len(warnings) == 1 and warnings[0].startswith("cannot publish")


def test_a_hung_redis_holds_the_monitor_s_read_no_longer_than_the_timeout():
    """Redis accepts the connection and never answers: the monitor's pass (and with it every
    escalation) must not wait for it."""

    async def scenario():
        async def swallow(reader, writer):
            await reader.read()  # reads, never answers

        server = await asyncio.start_server(swallow, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        client = redis.Redis(host="127.0.0.1", port=port)
        waiting = shared(client, "p.", "monitor", set())
        # Without its own timeout the read would wait forever: this one would then fail.
        seen = await asyncio.wait_for(waiting.elsewhere(), 10 * READ_TIMEOUT_S)
        await client.aclose()
        server.close()
        return seen

    assert asyncio.run(scenario()) == set()
