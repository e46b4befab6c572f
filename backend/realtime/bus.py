"""Alarm fan-out. A committed alarm goes to this process's browsers at once and, when
`redis_url` is set, through Redis pub/sub to every other backend replica, which hands it to its
own browsers (each replica ignores its own messages). The fleet's news (a robot's running model
or a deployment changed) travels the same way on a channel of its own (`<channel>.fleet`: a
replica that knows only alarms never sees it).

Fleet news is coalesced: one fleet message is on its way at a time, and the news that arrives
meanwhile travels together in the next. A thousand robots saying hello to the replica left
after a kill -9 made a thousand Redis publishes at once, past redis-py's pool (100
connections, then "Too many connections"), and as many messages to every engineer's page.
Publishes wait for a free pooled connection rather than fail: an alarm not fanned out is an
alarm missing from the other replicas' boards.

A commit's alarms go out together (`publish_many`): each is encoded once, for the browsers and
for Redis, and Redis gets them in one round trip (a pipeline of PUBLISHes, the same messages a
single publish sends). With a hundred robots in Emergency a flush pushed dozens of alarms one
awaited publish after another, and the robots' acks, sent after the pushes, waited for them."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import uuid
from collections.abc import Callable

from backend.realtime.hub import BrowserHub, encode

log = logging.getLogger(__name__)
REDIS_MAX_CONNECTIONS = 32


class AlarmBus:
    def __init__(self, hub: BrowserHub, redis_url: str | None, channel: str) -> None:
        self.hub = hub
        self.origin = uuid.uuid4().hex
        self._redis_url = redis_url
        self._channel = channel
        self._fleet_channel = f"{channel}.fleet"
        self._redis = None
        self._listener: asyncio.Task | None = None
        self.subscribed = asyncio.Event()
        # Called with each alarm change of another replica (the alarm distribution's sender
        # on the replica that runs it looks at once for the change's queued message).
        self.on_remote: list[Callable[[dict], None]] = []
        self._fleet_news: set[str] = set()
        self._fleet_due = False  # news waits (maybe of no robot: the deployments changed)
        self._fleet_sending = False

    async def start(self) -> None:
        if not self._redis_url:
            return
        import redis.asyncio as redis

        pool = redis.BlockingConnectionPool.from_url(
            self._redis_url, max_connections=REDIS_MAX_CONNECTIONS, timeout=5
        )
        self._redis = redis.Redis(connection_pool=pool)
        self._listener = asyncio.create_task(self._listen(), name="alarm-bus")
        # Serve only once subscribed, so no alarm of another replica is missed at start-up.
        try:
            await asyncio.wait_for(self.subscribed.wait(), 5)
        except TimeoutError:
            log.warning("Redis at %s not reachable: alarms stay local until it is", self._redis_url)

    async def stop(self) -> None:
        if self._listener is not None:
            self._listener.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._listener
        if self._redis is not None:
            await self._redis.aclose()

    @property
    def configured(self) -> bool:
        return bool(self._redis_url)

    @property
    def redis(self):
        """The started Redis client (None without `redis_url`), for the replicas' other
        shared state (backend.ingest.waiting)."""
        return self._redis

    async def ping(self) -> None:
        """Raise unless Redis answers (readiness); nothing to check without `redis_url`."""
        if not self._redis_url:
            return
        if self._redis is None:
            raise RuntimeError("Redis client not started")
        await self._redis.ping()

    async def publish(self, alarm: dict) -> None:
        """Push one committed alarm (its AlarmOut JSON) to every browser allowed to see it."""
        await self.publish_many([alarm])

    async def publish_many(self, alarms: list[dict]) -> None:
        """Push committed alarms, in order, to every browser allowed to see them."""
        encoded = [encode(alarm) for alarm in alarms]
        await self.hub.publish_encoded(list(zip(alarms, encoded, strict=True)))
        if self._redis is None or not alarms:
            return
        origin = json.dumps(self.origin)
        try:
            async with self._redis.pipeline(transaction=False) as pipeline:
                for text in encoded:
                    pipeline.publish(self._channel, f'{{"origin":{origin},"alarm":{text}}}')
                await pipeline.execute()
        except Exception as error:  # Redis down: local browsers have it; others see it on reload
            ids = [alarm.get("id") for alarm in alarms]
            log.warning("alarms %s not fanned out through Redis: %s", ids, error)

    async def publish_fleet(self, robot_ids: list[str]) -> None:
        """Tell every fleet page (here and on the other replicas) these robots changed (none:
        the deployments did). Sent at once, unless a fleet message is on its way: then it goes
        with the next, together with the rest of the news that arrived meanwhile."""
        self._fleet_news.update(robot_ids)
        self._fleet_due = True
        if self._fleet_sending:
            return
        self._fleet_sending = True
        try:
            while self._fleet_due:
                self._fleet_due = False
                news, self._fleet_news = sorted(self._fleet_news), set()
                await self._send_fleet(news)
        finally:
            self._fleet_sending = False

    async def _send_fleet(self, robot_ids: list[str]) -> None:
        await self.hub.publish_fleet(robot_ids)
        if self._redis is None:
            return
        try:
            await self._redis.publish(
                self._fleet_channel, json.dumps({"origin": self.origin, "fleet": robot_ids})
            )
        except Exception as error:  # Redis down: the other replicas' pages see it on their poll
            log.warning("fleet change of %s not fanned out through Redis: %s", robot_ids, error)

    async def _listen(self) -> None:
        while True:
            try:
                async with self._redis.pubsub() as pubsub:
                    await pubsub.subscribe(self._channel, self._fleet_channel)
                    self.subscribed.set()
                    async for message in pubsub.listen():
                        if message.get("type") != "message":
                            continue
                        payload = json.loads(message["data"])
                        if payload.get("origin") == self.origin:
                            continue
                        channel = message.get("channel")
                        if isinstance(channel, bytes):
                            channel = channel.decode()
                        if channel == self._fleet_channel:
                            await self.hub.publish_fleet(list(payload["fleet"]))
                        else:
                            await self.hub.publish_alarm(payload["alarm"])
                            for listener in self.on_remote:
                                listener(payload["alarm"])
            except asyncio.CancelledError:
                raise
            except Exception as error:
                self.subscribed.clear()
                log.warning("Redis alarm subscription lost (%s); retrying in 1 s", error)
                await asyncio.sleep(1)
