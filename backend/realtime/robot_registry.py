"""Which robots are connected to this backend process right now."""

from __future__ import annotations

from enum import StrEnum
from typing import Any


class ConnectionState(StrEnum):
    CONNECTED = "connected"
    DISCONNECTED = "disconnected"


class RobotRegistry:
    """robot id -> its live link (backend.realtime.robot_link.RobotConnection) in this process."""

    def __init__(self, on_change=None) -> None:
        self._sockets: dict[str, Any] = {}
        self._on_change = on_change

    def connect(self, robot_id: str, websocket: Any) -> Any | None:
        """Register a connection; returns the older connection of the same robot, if any."""
        previous = self._sockets.get(robot_id)
        self._sockets[robot_id] = websocket
        if self._on_change:
            self._on_change(len(self._sockets))
        return previous if previous is not websocket else None

    def disconnect(self, robot_id: str, websocket: Any) -> None:
        if self._sockets.get(robot_id) is websocket:
            del self._sockets[robot_id]
        if self._on_change:
            self._on_change(len(self._sockets))

    def state(self, robot_id: str) -> ConnectionState:
        return (
            ConnectionState.CONNECTED if robot_id in self._sockets else ConnectionState.DISCONNECTED
        )

    def socket(self, robot_id: str) -> Any | None:
        return self._sockets.get(robot_id)

    def __len__(self) -> int:
        return len(self._sockets)
