"""One robot's live link to this backend process: every send to a robot (welcome, ack, model
assignment, close) goes through its `RobotConnection`, one at a time under one lock, so an
assignment pushed by a rollout never interleaves with the writer's acks or a close."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import WebSocket
from pydantic import BaseModel

from vigil import protocol

# Close reasons are limited to 123 bytes by the websocket protocol.
MAX_REASON_BYTES = 123


def http_base(websocket: WebSocket) -> str:
    """The backend's HTTP address as the robot reached it (for model download URLs)."""
    url = websocket.base_url
    scheme = {"ws": "http", "wss": "https"}.get(url.scheme, url.scheme)
    return str(url.replace(scheme=scheme)).rstrip("/")


class RobotConnection:
    """One robot's websocket as the writer, the registry and the token routes see it."""

    def __init__(self, websocket: WebSocket, robot_id: str, ward: str | None = None) -> None:
        self.websocket = websocket
        self.robot_id = robot_id
        self.ward = ward  # where an alarm pushed before it is stored goes
        self.closed = False
        self.base_url = http_base(websocket)
        #: Transport ids this link has checked: this robot's, or none's (yet).
        self.checked_transports: set[str] = set()
        self._lock = asyncio.Lock()

    async def send(self, message: BaseModel | str) -> bool:
        """Send one message; False (and the link closed) if the robot went away."""
        text = message if isinstance(message, str) else message.model_dump_json()
        async with self._lock:
            if self.closed:
                return False
            try:
                await self.websocket.send_text(text)
            except Exception:  # the robot went away; it resends what it did not see acked
                self.closed = True
                return False
        return True

    async def send_ack(self, seq: int) -> None:
        await self.send(protocol.ack_json(seq))

    async def reject(self, code: int, reason: str) -> None:
        await self.close(code, reason)

    async def close(self, code: int, reason: str) -> None:
        async with self._lock:
            if self.closed:
                return
            self.closed = True
            with contextlib.suppress(Exception):
                await self.websocket.close(
                    code, reason.encode()[:MAX_REASON_BYTES].decode("ascii", "ignore")
                )
