"""Live alarm push to browsers, filtered by the user's ward and role."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass, field

from fastapi import WebSocket

from backend.models.users import Role

log = logging.getLogger(__name__)

ALARM_VIEWERS = frozenset({Role.NURSE, Role.ENGINEER, Role.ADMIN})


@dataclass(eq=False)
class BrowserConnection:
    websocket: WebSocket
    user_id: int
    role: Role
    ward: str | None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    def can_see(self, ward: str) -> bool:
        if self.role not in ALARM_VIEWERS:
            return False
        return not (self.role == Role.NURSE and self.ward and self.ward != ward)


class BrowserHub:
    def __init__(self) -> None:
        self._connections: set[BrowserConnection] = set()

    def add(self, connection: BrowserConnection) -> None:
        self._connections.add(connection)

    def remove(self, connection: BrowserConnection) -> None:
        self._connections.discard(connection)

    @property
    def size(self) -> int:
        return len(self._connections)

    async def send(self, connection: BrowserConnection, message: dict) -> None:
        async with connection.lock:
            await connection.websocket.send_json(message)

    async def publish_alarm(self, alarm: dict) -> None:
        """Push one committed alarm to every browser allowed to see it."""
        message = {"type": "alarm", "alarm": alarm}
        targets = [c for c in self._connections if c.can_see(alarm["ward"])]
        results = await asyncio.gather(
            *(self.send(c, message) for c in targets), return_exceptions=True
        )
        for connection, result in zip(targets, results, strict=True):
            if isinstance(result, Exception):
                log.info("dropping browser connection of user %s: %s", connection.user_id, result)
                self.remove(connection)
