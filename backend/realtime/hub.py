"""Live push to browsers: alarms, filtered by the user's ward and role, and the fleet's news
(a robot's running model or a deployment changed) to those who may see the fleet."""

from __future__ import annotations

import asyncio
import json
import logging
from collections import OrderedDict
from dataclasses import dataclass, field
from datetime import UTC, datetime

from fastapi import WebSocket

from backend.models.users import Role
from backend.permissions import PERMISSIONS
from backend.wards import HasWard, sees_ward

log = logging.getLogger(__name__)

ALARM_VIEWERS = frozenset({Role.NURSE, Role.ENGINEER, Role.ADMIN})
#: Who is told the fleet changed: whoever may read it (the fleet page, GET /api/fleet).
FLEET_VIEWERS = PERMISSIONS[("GET", "/api/fleet")]


def encode(message: dict) -> str:
    """JSON text as Starlette's send_json writes it (encoded once for every browser)."""
    return json.dumps(message, separators=(",", ":"), ensure_ascii=False)


def sees(viewer: HasWard, ward: str) -> bool:
    """Whether a browser of this user is shown alarms of `ward` (the one ward rule)."""
    return viewer.role in ALARM_VIEWERS and sees_ward(viewer, ward)


@dataclass(frozen=True, slots=True)
class Viewer:
    """Who is looking at an alarm board right now (a snapshot of one connection)."""

    user_id: int
    role: Role
    ward: str | None

    def can_see(self, ward: str) -> bool:
        return sees(self, ward)


@dataclass(eq=False)
class BrowserConnection:
    websocket: WebSocket
    user_id: int
    role: Role
    ward: str | None
    jti: str = ""  # the browser session it was opened with (logout closes it)
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)

    def can_see(self, ward: str) -> bool:
        return sees(self, ward)


#: Alarms the hub remembers (the last push of each key), for reads storage cannot answer.
RECENT_ALARMS = 5000


@dataclass(frozen=True, slots=True)
class AlarmFilter:
    state: str | None = None
    kind: str | None = None
    ward: str | None = None
    robot_id: str | None = None
    since: datetime | None = None
    until: datetime | None = None

    def matches(self, alarm: dict) -> bool:
        raised = _aware(datetime.fromisoformat(alarm["raised_at"]))
        return (
            (self.state is None or alarm["state"] == self.state)
            and (self.kind is None or alarm["kind"] == self.kind)
            and (self.ward is None or alarm["ward"] == self.ward)
            and (self.robot_id is None or alarm["robot_id"] == self.robot_id)
            and (self.since is None or raised >= _aware(self.since))
            and (self.until is None or raised < _aware(self.until))
        )


def _aware(at: datetime) -> datetime:
    return at if at.tzinfo is not None else at.replace(tzinfo=UTC)


class BrowserHub:
    def __init__(self) -> None:
        self._connections: set[BrowserConnection] = set()
        # key -> the last push of that alarm (stored or not yet stored), newest last.
        self._recent: OrderedDict[str, dict] = OrderedDict()

    def add(self, connection: BrowserConnection) -> None:
        self._connections.add(connection)

    def remove(self, connection: BrowserConnection) -> None:
        self._connections.discard(connection)

    def viewers(self) -> list[Viewer]:
        """Who has a board open on this backend now (read on the event loop)."""
        return [Viewer(c.user_id, c.role, c.ward) for c in self._connections]

    @property
    def size(self) -> int:
        return len(self._connections)

    async def send(self, connection: BrowserConnection, message: dict) -> None:
        await self._send_texts(connection, [encode(message)])

    async def _send_texts(self, connection: BrowserConnection, texts: list[str]) -> None:
        async with connection.lock:
            for text in texts:
                await connection.websocket.send_text(text)

    async def publish_alarm(self, alarm: dict) -> None:
        """Push one committed alarm to every browser allowed to see it."""
        await self.publish_encoded([(alarm, encode(alarm))])

    async def publish_encoded(self, alarms: list[tuple[dict, str]]) -> None:
        """Push alarms (each with its JSON text, encoded once for every browser), in order,
        to every browser allowed to see them."""
        for alarm, _ in alarms:
            self._remember(alarm)
        messages = [(alarm["ward"], f'{{"type":"alarm","alarm":{text}}}') for alarm, text in alarms]
        targets, texts = [], []
        for connection in self._connections:
            seen = [message for ward, message in messages if connection.can_see(ward)]
            if seen:
                targets.append(connection)
                texts.append(seen)
        results = await asyncio.gather(
            *(self._send_texts(c, t) for c, t in zip(targets, texts, strict=True)),
            return_exceptions=True,
        )
        self._drop_failed(targets, results)

    async def publish_fleet(self, robot_ids: list[str]) -> None:
        """Tell every browser that may see the fleet that it changed (these robots' rows, or
        only the deployments when empty): the fleet page reloads at once, not at its next
        poll. Only the robot ids travel: the page reads the rest through its own scope."""
        message = {"type": "fleet", "robots": sorted(robot_ids)}
        await self._broadcast([c for c in self._connections if c.role in FLEET_VIEWERS], message)

    async def _broadcast(self, targets: list[BrowserConnection], message: dict) -> None:
        text = encode(message)
        results = await asyncio.gather(
            *(self._send_texts(c, [text]) for c in targets), return_exceptions=True
        )
        self._drop_failed(targets, results)

    def _drop_failed(self, targets: list[BrowserConnection], results: list) -> None:
        for connection, result in zip(targets, results, strict=True):
            if isinstance(result, Exception):
                log.info("dropping browser connection of user %s: %s", connection.user_id, result)
                self.remove(connection)

    def _remember(self, alarm: dict) -> None:
        key = (
            alarm.get("key")
            or f"{alarm['robot_id']}/{alarm.get('transport_id') or ''}/{alarm['kind']}"
        )
        self._recent.pop(key, None)
        self._recent[key] = alarm
        while len(self._recent) > RECENT_ALARMS:
            self._recent.popitem(last=False)

    def known_alarms(self, viewer: HasWard, where: AlarmFilter, limit: int = 200) -> list[dict]:
        """The alarms this hub pushed since the process started (the last push of each), that
        `viewer` may see and `where` selects, newest raised first: what the alarm list answers
        when storage does not (marked stale by the caller; not-yet-stored ones say so)."""
        found = [a for a in self._recent.values() if sees(viewer, a["ward"]) and where.matches(a)]
        found.sort(key=lambda a: a["raised_at"], reverse=True)
        return found[:limit]

    async def close_where(self, matches, code: int, reason: str) -> int:
        """Close (and forget) every connection `matches(connection)` selects; returns how many."""
        targets = [c for c in self._connections if matches(c)]
        for connection in targets:
            self.remove(connection)
            try:
                async with connection.lock:
                    await connection.websocket.close(code, reason)
            except Exception as error:  # already gone: nothing left to close
                log.info(
                    "browser connection of user %s already closed: %s", connection.user_id, error
                )
        return len(targets)

    async def close_user(self, user_id: int, code: int, reason: str) -> int:
        return await self.close_where(lambda c: c.user_id == user_id, code, reason)

    async def close_session(self, jti: str, code: int, reason: str) -> int:
        return await self.close_where(lambda c: c.jti == jti, code, reason)
