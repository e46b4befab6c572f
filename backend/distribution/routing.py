"""Which Alert Manager serves which ward, and how the alarm domain learns it.

The routing is built once at start-up from the settings and handed to every session of the
process through the session factory's `info` (`attach`), so the alarm service, which sees only
its session, queues a change's message in the change's own transaction (`of(session)`). A
process without a routing (the worker, the CLI, distribution off) queues nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from sqlalchemy.orm import Session, sessionmaker

_KEY = "vigil.distribution.routing"
_WAKE = "vigil.distribution.wake"


@dataclass(frozen=True, slots=True)
class Destination:
    host: str
    port: int

    @classmethod
    def parse(cls, text: str, name: str = "alert_manager") -> Destination:
        """ "host:port" (a setting); ValueError naming the setting."""
        host, _, port = text.strip().rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"{name}: expected host:port, got {text!r}")
        return cls(host.strip("[]"), int(port))

    def __str__(self) -> str:
        return f"{self.host}:{self.port}"


@dataclass(frozen=True, slots=True)
class Routing:
    """The Alert Manager of each ward: `by_ward` first, else `default` (None: that ward's
    alarms stay on the board)."""

    default: Destination | None
    by_ward: dict[str, Destination] = field(default_factory=dict)
    facility: str = "HOSPITAL"

    @classmethod
    def from_settings(
        cls, default: str | None, by_ward: dict[str, str], facility: str
    ) -> Routing | None:
        if not default and not by_ward:
            return None
        return cls(
            Destination.parse(default) if default else None,
            {w: Destination.parse(d, f"alert_manager_by_ward[{w}]") for w, d in by_ward.items()},
            facility,
        )

    def destination_for(self, ward: str) -> Destination | None:
        return self.by_ward.get(ward, self.default)

    def destinations(self) -> list[Destination]:
        found = ([self.default] if self.default else []) + list(self.by_ward.values())
        return list(dict.fromkeys(found))

    def wards_of(self, destination: Destination, known_wards: list[str]) -> list[str]:
        """The wards (of `known_wards` and those named in `by_ward`) it serves."""
        wards = dict.fromkeys([*known_wards, *self.by_ward])
        return sorted(w for w in wards if self.destination_for(w) == destination)


def attach(
    factory: sessionmaker[Session],
    routing: Routing | None,
    wake: Callable[[], None] | None = None,
) -> None:
    """Every session of `factory` knows the routing (None: distribution off), and `wake`, the
    sender's bell, rung after a unit that queued a message commits."""
    info = dict(factory.kw.get("info") or {})
    info[_KEY] = routing
    info[_WAKE] = wake
    factory.configure(info=info)


def of(session: Session) -> Routing | None:
    return session.info.get(_KEY)


def waker(session: Session) -> Callable[[], None] | None:
    return session.info.get(_WAKE)
