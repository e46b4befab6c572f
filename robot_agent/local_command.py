"""The local command output: behaviour changes to the robot's own controller, with no network.

A UNIX domain socket (setting `local_socket`) streams one JSON line per behaviour change to
every connected client, written from the decision path itself (`Behaviour` listeners run inside
`Pipeline.process`), never through the backend connection:

    {"state": "emergency_stop", "reason": "...", "since": 1733430000.123,
     "transport_id": "r1-...", "alarm_id": null, "event": "behaviour"}

A client gets the current state as its first line on connecting. `event` is "behaviour" for a
state change and "alarm_acknowledged" when a nurse acknowledged the alarm (state unchanged, plus
`acknowledged_by`). A client may send `{"command": "reset"}` (or the line `reset`): a local reset
of an emergency stop; the reply is a line `{"reset": true|false, "state": ...}`. The contract is
documented in docs/robot_agent.md.

The hook command (`alarm_hook`) is called on every behaviour change too, with
VIGIL_BEHAVIOUR_STATE, VIGIL_BEHAVIOUR_REASON, VIGIL_BEHAVIOUR_SINCE, VIGIL_BEHAVIOUR_EVENT,
VIGIL_ALARM_ROBOT, VIGIL_ALARM_TRANSPORT, VIGIL_ALARM_ID in its environment, and
VIGIL_ALARM_STATE=behaviour (acknowledged for an acknowledgement).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
from pathlib import Path

from robot_agent.alarm import spawn_hook
from robot_agent.behaviour import Behaviour, BehaviourChange

log = logging.getLogger(__name__)
MAX_LINE = 4096


def encode(change: BehaviourChange) -> bytes:
    return (json.dumps(change.as_dict(), separators=(",", ":")) + "\n").encode()


class LocalCommandServer:
    def __init__(self, path: Path, behaviour: Behaviour) -> None:
        self.path = Path(path)
        self.behaviour = behaviour
        self.clients: set[asyncio.StreamWriter] = set()
        self._server: asyncio.base_events.Server | None = None
        self.lines_sent = 0
        behaviour.listeners.append(self.send)

    async def start(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()  # a socket left by a previous run
        self._server = await asyncio.start_unix_server(self._client, path=str(self.path))
        os.chmod(self.path, 0o660)
        log.info("local command socket %s: behaviour changes for the controller", self.path)

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            for writer in list(self.clients):
                writer.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()
            self._server = None
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    async def run(self) -> None:
        await self.start()
        try:
            await asyncio.Future()
        finally:
            await self.close()

    def send(self, change: BehaviourChange) -> None:
        """Called on the decision path: write the line to every client without awaiting."""
        line = encode(change)
        for writer in list(self.clients):
            if writer.is_closing():
                self.clients.discard(writer)
                continue
            writer.write(line)
            self.lines_sent += 1

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.clients.add(writer)
        writer.write(encode(self.behaviour.current()))
        try:
            while line := await reader.readline():
                self._command(line[:MAX_LINE].decode(errors="replace").strip(), writer)
                await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError):
            pass
        finally:
            self.clients.discard(writer)
            writer.close()

    def _command(self, text: str, writer: asyncio.StreamWriter) -> None:
        if not text:
            return
        try:
            command = json.loads(text).get("command") if text.startswith("{") else text
        except (json.JSONDecodeError, AttributeError):
            command = None
        if command != "reset":
            reply = {"error": f"unknown command {text[:80]!r}: the one command is reset"}
        else:
            change = self.behaviour.reset(who="local socket")
            reply = {"reset": change is not None, "state": self.behaviour.state.value}
            if change is None:
                reply["reason"] = "not in emergency_stop: nothing to reset"
        writer.write((json.dumps(reply) + "\n").encode())


class BehaviourHook:
    """Runs the hook command on every behaviour change (and acknowledgement)."""

    def __init__(self, hook: list[str], robot_id: str) -> None:
        self.hook = hook
        self.robot_id = robot_id
        self.tasks: set[asyncio.Task] = set()

    def __call__(self, change: BehaviourChange) -> None:
        env = {
            **os.environ,
            # Existing hooks read VIGIL_ALARM_STATE: raised|cleared (robot_agent.alarm), and
            # behaviour|acknowledged for these calls.
            "VIGIL_ALARM_STATE": "acknowledged" if change.event != "behaviour" else "behaviour",
            "VIGIL_BEHAVIOUR_STATE": change.state,
            "VIGIL_BEHAVIOUR_REASON": change.reason,
            "VIGIL_BEHAVIOUR_SINCE": f"{change.since:.3f}",
            "VIGIL_BEHAVIOUR_EVENT": change.event,
            "VIGIL_ALARM_ROBOT": self.robot_id,
            "VIGIL_ALARM_TRANSPORT": change.transport_id or "",
            "VIGIL_ALARM_ID": "" if change.alarm_id is None else str(change.alarm_id),
        }
        spawn_hook(self.hook, env, change.state, self.tasks)
