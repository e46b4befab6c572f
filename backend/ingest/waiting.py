"""Which robots' messages wait in a frame writer, on this replica and on the others.

The alarm monitor raises "robot offline", "stream stalled" and "patient not seen" from what is
stored, so it skips the robots whose messages arrived but are not committed yet: their stored
times are stale because storage is behind, not because the robot fell silent (the writer's own
storage-stall actions make that visible). Only one replica runs the monitor, and a robot
streams to whichever replica it reached; without the others' waiting robots, the monitor
would raise them for robots streaming to a replica whose writer is behind.

Each replica writes its writer's waiting robots to Redis every `PUBLISH_S` under a key of its
own that expires after `TTL_S`, and its name into a set of replicas (so the reader asks for a
few keys, never scans Redis): a replica killed with -9 stops counting within seconds, and its
unacknowledged frames come again from the robots through another replica. Without Redis, or
while it does not answer, the monitor sees this replica's waiting robots only, which raises
more technical alarms, never fewer.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import Callable

log = logging.getLogger(__name__)

PUBLISH_S = 0.5
TTL_S = 3.0
MEMBERS_TTL_S = 60  # the set of replicas goes when none has published for this long
#: The monitor waits no longer than this for Redis: a hung Redis must not hold up escalations.
READ_TIMEOUT_S = 0.5


class SharedWaiting:
    def __init__(
        self,
        local: Callable[[], frozenset[str]],
        redis,
        prefix: str,
        replica: str,
        publish_s: float = PUBLISH_S,
        ttl_s: float = TTL_S,
    ) -> None:
        self._local = local
        self._redis = redis  # redis.asyncio.Redis, or None: this replica alone
        self._prefix = prefix
        self._replica = replica
        self._members = f"{prefix}replicas"  # the replicas that published (a set)
        self._publish_s = publish_s
        self._ttl_ms = int(ttl_s * 1000)
        self._task: asyncio.Task | None = None
        self._failing = False

    def start(self) -> None:
        if self._redis is not None:
            self._task = asyncio.create_task(self._run(), name="shared-waiting")

    async def stop(self) -> None:
        """Stop publishing and take this replica's robots away at once."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self._redis is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._withdraw(), READ_TIMEOUT_S)

    async def _withdraw(self) -> None:
        await self._redis.delete(self._key(self._replica))
        await self._redis.srem(self._members, self._replica)

    async def _run(self) -> None:
        while True:
            await self.publish()
            await asyncio.sleep(self._publish_s)

    def _key(self, replica: str) -> str:
        return f"{self._prefix}of.{replica}"

    async def publish(self) -> None:
        try:
            async with self._redis.pipeline(transaction=False) as pipeline:
                pipeline.set(
                    self._key(self._replica), json.dumps(sorted(self._local())), px=self._ttl_ms
                )
                pipeline.sadd(self._members, self._replica)
                pipeline.expire(self._members, MEMBERS_TTL_S)
                await pipeline.execute()
        except Exception as error:  # Redis away: the bus and readiness report it
            self._note_failure("publish", error)
        else:
            self._failing = False

    async def elsewhere(self) -> frozenset[str]:
        """The robots waiting in the other replicas' writers (empty without Redis, or when it
        does not answer within READ_TIMEOUT_S)."""
        if self._redis is None:
            return frozenset()
        try:
            return await asyncio.wait_for(self._read(), READ_TIMEOUT_S)
        except Exception as error:
            self._note_failure("read", error)
            return frozenset()

    async def _read(self) -> frozenset[str]:
        others = sorted(_text(m) for m in await self._redis.smembers(self._members))
        others = [replica for replica in others if replica != self._replica]
        values = await self._redis.mget([self._key(r) for r in others]) if others else []
        gone = [replica for replica, value in zip(others, values, strict=True) if not value]
        if gone:  # expired: killed, or stopped
            await self._redis.srem(self._members, *gone)
        return frozenset(robot for value in values if value for robot in json.loads(value))

    def _note_failure(self, what: str, error: Exception) -> None:
        if not self._failing:
            log.warning("cannot %s the waiting robots in Redis: %s", what, error)
        self._failing = True


def _text(key: bytes | str) -> str:
    return key.decode() if isinstance(key, bytes) else key
