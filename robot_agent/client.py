"""Websocket client: hello, resend what is unacknowledged, stream new frames, heartbeats,
model assignments; reconnects with exponential backoff. Raises a local alarm (log and a hook
command) when the backend is unreachable while an Emergency holds."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import random
import shlex
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus, InvalidURI

from robot_agent import __version__
from robot_agent.models import DownloadAuth, ModelManager, ModelRefused
from robot_agent.outbox import Outbox
from vigil import protocol
from vigil.protocol import Heartbeat, Hello, ModelAssignment

log = logging.getLogger("robot_agent.client")
FATAL_CLOSE_CODES = {
    protocol.CLOSE_UNAUTHORIZED: "the backend refused the robot id or token",
    protocol.CLOSE_PROTOCOL_VERSION: "the backend does not speak this protocol version",
}


class LinkState(StrEnum):
    CONNECTING = "connecting"
    CONNECTED = "connected"  # welcome received
    WAITING = "waiting"  # backing off before the next attempt
    STOPPED = "stopped"


class FatalConnectionError(RuntimeError):
    pass


@dataclass
class Backoff:
    """Exponential backoff with full jitter: attempt n waits up to min(cap, base * 2**n)."""

    base_s: float = 0.2
    cap_s: float = 10.0
    jitter: bool = True
    attempt: int = 0
    rng: random.Random = field(default_factory=random.Random)

    def next_delay(self) -> float:
        ceiling = min(self.cap_s, self.base_s * 2**self.attempt)
        self.attempt += 1
        return self.rng.uniform(ceiling / 2, ceiling) if self.jitter else ceiling

    def reset(self) -> None:
        self.attempt = 0


class LocalAlarm:
    """Raised once per Emergency while the backend cannot be told; cleared when it can."""

    def __init__(
        self, robot_id: str, hook_command: str | None = None, grace_s: float = 2.0
    ) -> None:
        self.robot_id = robot_id
        self.hook_command = hook_command
        self.grace_s = grace_s
        self.raised = False
        self.raised_count = 0
        self._since: float | None = None

    def update(self, emergency_holds: bool, backend_reachable: bool, now: float | None = None):
        now = time.monotonic() if now is None else now
        if not emergency_holds or backend_reachable:
            if self.raised:
                log.warning("local alarm cleared (backend reachable again or no Emergency)")
            self.raised, self._since = False, None
            return
        self._since = self._since or now
        if not self.raised and now - self._since >= self.grace_s:
            self.raised = True
            self.raised_count += 1
            log.error(
                "LOCAL ALARM: robot %s sees an EMERGENCY and cannot reach the backend",
                self.robot_id,
            )
            if self.hook_command:
                env = {
                    **os.environ,
                    "VIGIL_ROBOT_ID": self.robot_id,
                    "VIGIL_ALARM": "emergency-backend-unreachable",
                }
                try:
                    subprocess.Popen(shlex.split(self.hook_command), env=env)
                except OSError as error:
                    log.error("alarm hook %r failed: %s", self.hook_command, error)


class RobotClient:
    def __init__(
        self,
        url: str,
        robot_id: str,
        token: str,
        outbox: Outbox,
        models: ModelManager | None = None,
        heartbeat_s: float = 5.0,
        backoff: Backoff | None = None,
        batch_size: int = 200,
        on_state: Callable[[LinkState], None] | None = None,
    ) -> None:
        self.url = url
        self.robot_id = robot_id
        self.token = token
        self.outbox = outbox
        self.models = models
        self.heartbeat_s = heartbeat_s
        self.backoff = backoff or Backoff()
        self.batch_size = min(batch_size, protocol.MAX_FRAMES_PER_BATCH)
        self.state = LinkState.STOPPED
        self.on_state = on_state
        self.acked_seq: int | None = None
        self.connections = 0
        self._new_items = asyncio.Event()
        self._ws = None

    @property
    def connected(self) -> bool:
        return self.state is LinkState.CONNECTED

    def notify(self) -> None:
        """Something new is in the outbox."""
        self._new_items.set()

    def _set(self, state: LinkState) -> None:
        if state is not self.state:
            self.state = state
            if self.on_state:
                self.on_state(state)

    async def run(self, stop: asyncio.Event) -> None:
        while not stop.is_set():
            self._set(LinkState.CONNECTING)
            try:
                await self._session(stop)
            except FatalConnectionError:
                self._set(LinkState.STOPPED)
                raise
            except (TimeoutError, OSError, ConnectionClosed, InvalidStatus) as error:
                code = getattr(getattr(error, "rcvd", None), "code", None)
                if code in FATAL_CLOSE_CODES:
                    reason = error.rcvd.reason  # type: ignore[union-attr]
                    raise FatalConnectionError(
                        f"{FATAL_CLOSE_CODES[code]} (close {code}: {reason})"
                    ) from error
                log.warning("backend unreachable (%s)", _describe(error))
            except InvalidURI as error:
                raise FatalConnectionError(f"backend_url: {error}") from error
            if stop.is_set():
                break
            self._set(LinkState.WAITING)
            delay = self.backoff.next_delay()
            log.info("reconnecting in %.1f s", delay)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), delay)
        self._set(LinkState.STOPPED)

    async def _session(self, stop: asyncio.Event) -> None:
        async with connect(
            self.url,
            open_timeout=5,
            max_size=protocol.MAX_MESSAGE_BYTES,
            ping_interval=10,
            ping_timeout=10,
        ) as ws:
            running = self.models.running_version if self.models else None
            await ws.send(
                Hello(
                    robot_id=self.robot_id,
                    token=self.token,
                    agent_version=__version__,
                    running_model=running,
                ).model_dump_json()
            )
            welcome = protocol.server_message_adapter.validate_json(
                await asyncio.wait_for(ws.recv(), 10)
            )
            if not isinstance(welcome, protocol.Welcome):
                raise FatalConnectionError(f"expected welcome, got {welcome.type}")
            self.outbox.welcome(welcome.last_seq)
            self.acked_seq = welcome.last_seq
            self.connections += 1
            self.backoff.reset()
            self._set(LinkState.CONNECTED)
            log.info(
                "connected to %s as %s; backend holds frames up to %s; %d to resend",
                self.url,
                self.robot_id,
                welcome.last_seq,
                len(self.outbox),
            )
            self._ws = ws
            tasks = [
                asyncio.create_task(self._send_loop(ws)),
                asyncio.create_task(self._receive_loop(ws)),
                asyncio.create_task(self._heartbeat_loop(ws)),
                asyncio.create_task(stop.wait()),
            ]
            try:
                done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in done:
                    if task.exception() is not None:
                        raise task.exception()  # type: ignore[misc]
            finally:
                self._ws = None
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)

    async def _send_loop(self, ws) -> None:
        cursor = 0
        while True:
            self._new_items.clear()
            items = self.outbox.pending(after_id=cursor, limit=self.batch_size)
            if not items:
                await self._new_items.wait()
                continue
            frames: list[dict] = []
            for item in items:
                if item.seq is None:
                    if frames:
                        await ws.send(_batch(frames))
                        frames = []
                    await ws.send(json.dumps(item.body))
                else:
                    frames.append(item.body)
                cursor = item.id
            if frames:
                await ws.send(_batch(frames))

    async def _receive_loop(self, ws) -> None:
        async for raw in ws:
            message = protocol.server_message_adapter.validate_json(raw)
            if isinstance(message, protocol.Ack):
                self.outbox.ack(message.seq)
                self.acked_seq = message.seq
            elif isinstance(message, ModelAssignment):
                asyncio.create_task(self._install(ws, message))
            elif isinstance(message, protocol.ServerError):
                log.warning("backend says: %s", message.message)

    async def _install(self, ws, assignment: ModelAssignment) -> None:
        if self.models is None:
            log.warning(
                "model %s assigned, but this agent streams ground truth: ignored",
                assignment.version,
            )
            return
        if assignment.shadow:
            log.info(
                "shadow model %s assigned: shadow decisions are not run on this agent",
                assignment.version,
            )
            return
        with contextlib.suppress(ModelRefused):
            await asyncio.to_thread(
                self.models.install, assignment, DownloadAuth(self.robot_id, self.token)
            )
        # report the version that runs (the new one once the frame loop swapped it in)
        for _ in range(50):
            if self.models._ready is None:  # noqa: SLF001 - swapped in by the frame loop
                break
            await asyncio.sleep(0.02)
        await self.send_heartbeat(ws)

    async def send_heartbeat(self, ws=None) -> None:
        ws = ws or self._ws
        if ws is None:
            return
        running = self.models.running_version if self.models else None
        await ws.send(Heartbeat(ts=time.time(), running_model=running).model_dump_json())

    async def _heartbeat_loop(self, ws) -> None:
        while True:
            await self.send_heartbeat(ws)
            await asyncio.sleep(self.heartbeat_s)


def _batch(frames: list[dict]) -> str:
    return '{"type":"frames","frames":' + json.dumps(frames, separators=(",", ":")) + "}"


def _describe(error: BaseException) -> str:
    if isinstance(error, ConnectionClosed) and error.rcvd is not None:
        return f"connection closed with code {error.rcvd.code}: {error.rcvd.reason}"
    return f"{type(error).__name__}: {error}" if str(error) else type(error).__name__
