"""The robot's websocket link to the backend.

hello -> welcome{last_seq}: the outbox forgets what the backend already has, then everything
still unacknowledged is sent again in order (frame batches and transport messages), new frames
follow as they are queued, `ack{seq}` trims the outbox, heartbeats report the running model (and
the sha256 of its file) and the outbox's state, `assign_model` goes to the agent. A lost
connection is retried with exponential backoff and jitter; a refused token or protocol version
stops the link (LinkFatal).

With several backend URLs (replicas behind no common address), a lost or refused connection
goes to the next URL at once; the backoff starts only once every URL has failed in a row, so a
robot whose replica died streams to another within its connect time, not its backoff.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable, Iterable, Sequence

from pydantic import ValidationError
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI

from robot_agent.backoff import Backoff
from robot_agent.outbox import Outbox
from vigil import protocol
from vigil.inputs import normalise
from vigil.protocol import (
    Ack,
    AlarmAcknowledged,
    AlarmResolved,
    Heartbeat,
    Hello,
    ModelAssignment,
    ServerError,
    Welcome,
    server_message_adapter,
)

log = logging.getLogger(__name__)
AGENT_VERSION = "vigil-robot 0.1"
FATAL_CLOSE_CODES = {
    protocol.CLOSE_UNAUTHORIZED: "the backend refused this robot's id or token",
    protocol.CLOSE_PROTOCOL_VERSION: "the backend does not speak this agent's protocol version",
}


class LinkFatal(Exception):
    """The backend refused this robot for good (wrong token, protocol version)."""


class RobotLink:
    def __init__(
        self,
        url: str | Sequence[str],
        robot_id: str,
        token: str,
        outbox: Outbox,
        running_model: Callable[[], str | None],
        inputs: Iterable[str] | None = None,
        on_assignment: Callable[[ModelAssignment], Awaitable[None]] | None = None,
        on_welcome: Callable[[Welcome], None] | None = None,
        loaded_models: Callable[[], dict[str, str]] | None = None,
        heartbeat_s: float = 5.0,
        batch_frames: int = 100,
        backoff: Backoff | None = None,
        on_alarm: Callable[[AlarmAcknowledged | AlarmResolved], None] | None = None,
    ) -> None:
        self.urls = [url] if isinstance(url, str) else list(url)
        if not self.urls:
            raise ValueError("RobotLink needs at least one backend URL")
        self._url_index = 0
        self._failed_in_row = 0  # connections that failed since the last welcome
        self.robot_id, self.token = robot_id, token
        self.outbox = outbox
        self.running_model = running_model
        self.inputs = None if inputs is None else normalise(inputs)  # told in the hello
        self.on_assignment = on_assignment
        self.on_welcome = on_welcome
        self.on_alarm = on_alarm  # a nurse acknowledged / resolved this robot's alarm
        # sha256 of the model files it runs (hello: running_sha256, fallback_model/_sha256).
        self.loaded_models = loaded_models or dict
        self.heartbeat_s = heartbeat_s
        self.batch_frames = batch_frames
        self.backoff = backoff or Backoff()
        self.connected = False
        self.last_problem: str | None = "not connected yet"
        self.model_error: str | None = None
        self.connections = 0
        self.sent_row = 0  # outbox row id of the last message sent on the current connection
        self.sent_at = 0.0
        self._queued = asyncio.Event()
        self._heartbeat_now = asyncio.Event()
        self._tasks: set[asyncio.Task] = set()

    @property
    def url(self) -> str:
        """The backend URL the link uses now (or tries next)."""
        return self.urls[self._url_index]

    # --- called by the agent -----------------------------------------------------------------
    def notify_queued(self) -> None:
        """New messages are in the outbox."""
        self._queued.set()

    def heartbeat_now(self) -> None:
        self._heartbeat_now.set()

    # --- the connection loop -----------------------------------------------------------------
    async def run(self) -> None:
        """Connect, stream, reconnect; returns only by cancellation or LinkFatal."""
        while True:
            try:
                async with connect(
                    self.url,
                    open_timeout=10,
                    close_timeout=2,
                    ping_interval=5,
                    ping_timeout=10,
                    max_size=4 * protocol.MAX_MESSAGE_BYTES,
                ) as socket:
                    await self._session(socket)
            except ConnectionClosed as closed:
                code = closed.rcvd.code if closed.rcvd else None
                reason = closed.rcvd.reason if closed.rcvd else "no close frame"
                if code in FATAL_CLOSE_CODES:
                    self.last_problem = f"{FATAL_CLOSE_CODES[code]} ({code} {reason})"
                    log.error("robot %s: %s: giving up", self.robot_id, self.last_problem)
                    raise LinkFatal(self.last_problem) from None
                self.last_problem = f"connection closed ({code} {reason})".replace(" )", ")")
            except (OSError, TimeoutError, InvalidHandshake) as error:
                self.last_problem = f"backend unreachable ({type(error).__name__}: {error})"
            except InvalidURI as error:
                raise LinkFatal(f"backend_url is not a websocket URL: {error}") from None
            except (LinkFatal, asyncio.CancelledError):
                raise
            except Exception as error:  # e.g. an unreadable welcome: keep trying, say what
                log.exception("robot %s: unexpected error on the link", self.robot_id)
                self.last_problem = f"unexpected error ({type(error).__name__}: {error})"
            finally:
                self.connected = False
            self._failed_in_row += 1
            if len(self.urls) > 1:
                failed = self.url
                self._url_index = (self._url_index + 1) % len(self.urls)
                if self._failed_in_row < len(self.urls):
                    log.warning(
                        "robot %s: %s at %s; trying %s now",
                        self.robot_id,
                        self.last_problem,
                        failed,
                        self.url,
                    )
                    continue
                self._failed_in_row = 0  # each URL gets its turn again after the delay
            delay = self.backoff.next_delay()
            log.warning(
                "robot %s: %s; %d frames waiting in the outbox; retrying in %.1f s",
                self.robot_id,
                self.last_problem,
                self.outbox.status().pending_frames,
                delay,
            )
            await asyncio.sleep(delay)

    async def _session(self, socket: ClientConnection) -> None:
        hello = Hello(
            robot_id=self.robot_id,
            token=self.token,
            agent_version=AGENT_VERSION,
            running_model=self.running_model(),
            inputs=self.inputs,
            **self.loaded_models(),
        )
        await socket.send(hello.model_dump_json(exclude_none=True))
        welcome = await self._receive_welcome(socket)
        before = self.outbox.status().pending_frames
        self.outbox.on_welcome(welcome.last_seq)
        pending = self.outbox.status()
        if self.on_welcome is not None:
            self.on_welcome(welcome)  # checks the models it runs against the registry's sha256
        self.connected = True
        self.last_problem = None
        self.connections += 1
        self._failed_in_row = 0
        self.backoff.reset()
        log.info(
            "robot %s connected to %s: backend has frames up to seq %s; sending %d unacknowledged "
            "frames (%d were already stored)",
            self.robot_id,
            self.url,
            welcome.last_seq,
            pending.pending_frames,
            before - pending.pending_frames,
        )
        tasks = [
            asyncio.create_task(self._send_loop(socket), name="send"),
            asyncio.create_task(self._receive_loop(socket), name="receive"),
            asyncio.create_task(self._heartbeat_loop(socket), name="heartbeat"),
        ]
        try:
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
            for task in done:
                task.result()  # re-raise what ended the session
        finally:
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task

    async def _receive_welcome(self, socket: ClientConnection) -> Welcome:
        raw = await asyncio.wait_for(socket.recv(), timeout=10)
        message = server_message_adapter.validate_json(raw)
        if not isinstance(message, Welcome):
            raise ConnectionError(f"expected welcome, got {message.type}")
        return message

    def delivered_all(self, settle_s: float = 1.0) -> bool:
        """Every frame acknowledged, and the transport messages queued after the last frame sent
        on a connection still open `settle_s` later (the backend never acknowledges those
        alone; they stay in the outbox and are sent again on the next start, harmlessly)."""
        status = self.outbox.status()
        if status.pending_frames:
            return False
        if not status.pending_messages:
            return True
        return (
            self.connected
            and self.sent_row >= self.outbox.last_row_id()
            and time.monotonic() - self.sent_at >= settle_s
        )

    async def _send_loop(self, socket: ClientConnection) -> None:
        cursor = 0  # outbox row id of the last message sent on this connection
        self.sent_row = 0
        while True:
            self._queued.clear()
            messages = self.outbox.pending(after_row=cursor, limit=self.batch_frames)
            if not messages:
                await self._queued.wait()
                continue
            frames: list[str] = []
            for message in messages:
                if message.seq is None:  # a transport message: flush the frames before it
                    if frames:
                        await socket.send(protocol.frame_batch_json(frames))
                        frames = []
                    await socket.send(message.text)
                else:
                    frames.append(message.text)
                cursor = message.row_id
            if frames:
                await socket.send(protocol.frame_batch_json(frames))
            self.sent_row, self.sent_at = cursor, time.monotonic()

    async def _receive_loop(self, socket: ClientConnection) -> None:
        async for raw in socket:
            try:
                message = server_message_adapter.validate_json(raw)
            except ValidationError as error:
                log.warning(
                    "robot %s: unreadable message from the backend: %s",
                    self.robot_id,
                    error.errors()[0]["msg"],
                )
                continue
            if isinstance(message, Ack):
                self.outbox.acknowledge(message.seq)
            elif isinstance(message, ModelAssignment):
                if self.on_assignment is not None:
                    task = asyncio.create_task(self.on_assignment(message))
                    self._tasks.add(task)
                    task.add_done_callback(self._tasks.discard)
            elif isinstance(message, AlarmAcknowledged | AlarmResolved):
                if self.on_alarm is not None:
                    self.on_alarm(message)
            elif isinstance(message, ServerError):
                log.warning("robot %s: backend says: %s", self.robot_id, message.message)

    async def _heartbeat_loop(self, socket: ClientConnection) -> None:
        while True:
            status = self.outbox.status()
            heartbeat = Heartbeat(
                ts=time.time(),
                running_model=self.running_model(),
                running_sha256=self.loaded_models().get("running_sha256"),
                outbox_frames=status.pending_frames,
                dropped_frames=status.dropped_total,
                model_error=self.model_error,
            )
            await socket.send(heartbeat.model_dump_json(exclude_none=True))
            self._heartbeat_now.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._heartbeat_now.wait(), self.heartbeat_s)
