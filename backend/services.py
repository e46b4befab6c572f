"""The backend's services, built once in the lifespan and reached through typed dependencies
(`ServicesDep` and the `Annotated` aliases below), never as loose attributes of `app.state`.

`Services` is also where a committed unit of work's effects go (`backend.unit_of_work.Effects`):
an alarm to the bus, an assignment to the robots' links.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request, WebSocket
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from backend.accounts.gate import HashingGate
from backend.accounts.throttle import LoginThrottle
from backend.alarms.monitor import AlarmMonitor
from backend.distribution.listener import StatusListener
from backend.distribution.routing import Routing
from backend.distribution.sender import AlertSender
from backend.ingest.waiting import SharedWaiting
from backend.ingest.writer import FrameWriter
from backend.labelling.probability import LaneComputer
from backend.labelling.rgb import FrameCache, JpegCache
from backend.labelling.viewer3d import Viewer3D
from backend.leadership import Leadership
from backend.metrics import Metrics
from backend.realtime.bus import AlarmBus
from backend.realtime.hub import BrowserHub
from backend.realtime.robot_registry import RobotRegistry
from backend.registry.push import AssignmentPusher
from backend.settings import Settings
from backend.storage.service import SummaryCache


@dataclass
class Labelling:
    """The labelling workspace's process-wide tools."""

    rgb_frames: FrameCache
    rgb_jpegs: JpegCache
    model_lane: LaneComputer
    viewer3d: Viewer3D

    @classmethod
    def build(cls, settings: Settings) -> Labelling:
        return cls(
            FrameCache(settings.rgb_cache_frames),
            JpegCache(),
            LaneComputer(settings.labelling_model_dir),
            Viewer3D(settings.viser_host, settings.viser_port),
        )

    def close(self) -> None:
        self.viewer3d.stop()
        self.rgb_frames.close()


@dataclass(frozen=True)
class Fanout:
    """Where committed changes go: alarms and the fleet's news to the bus, assignments to the
    robots' links."""

    bus: AlarmBus
    assignments: AssignmentPusher
    robots: RobotRegistry | None = None

    async def send_to_robot(self, robot_id: str, text: str) -> None:
        """One message to a robot connected to this replica (a robot connected to another
        one does not get it: alarm_acknowledged / alarm_resolved are best effort)."""
        link = self.robots.socket(robot_id) if self.robots is not None else None
        if link is not None:
            await link.send(text)

    async def publish_alarm(self, alarm: dict) -> None:
        await self.bus.publish(alarm)

    async def publish_alarms(self, alarms: list[dict]) -> None:
        await self.bus.publish_many(alarms)

    async def push_assignments(self, robot_ids: list[str]) -> None:
        await self.assignments.push_to_robots(robot_ids)

    async def publish_fleet(self, robot_ids: list[str]) -> None:
        await self.bus.publish_fleet(robot_ids)


@dataclass
class Distribution:
    """Alarm distribution to the hospital's Alert Managers (IHE PCD ACM)."""

    routing: Routing
    sender: AlertSender
    listener: StatusListener | None

    async def start(self) -> None:
        self.sender.start()
        if self.listener is not None:
            await self.listener.start()

    async def stop(self) -> None:
        if self.listener is not None:
            await self.listener.stop()
        await self.sender.stop()


@dataclass
class Duties:
    """What runs on one replica at a time (`backend.leadership`): the alarm monitor and the
    alarm distribution's sender and listener."""

    monitor: AlarmMonitor
    distribution: Distribution | None

    async def start(self) -> None:
        self.monitor.start()
        if self.distribution is not None:
            await self.distribution.start()

    async def stop(self) -> None:
        if self.distribution is not None:
            await self.distribution.stop()
        await self.monitor.stop()


@dataclass
class Services:
    settings: Settings
    engine: Engine
    session_factory: sessionmaker[Session]
    metrics: Metrics
    hub: BrowserHub
    bus: AlarmBus
    robots: RobotRegistry
    assignments: AssignmentPusher
    effects: Fanout
    writer: FrameWriter
    waiting: SharedWaiting
    monitor: AlarmMonitor
    login_gate: HashingGate
    login_throttle: LoginThrottle
    labelling: Labelling
    storage_summary: SummaryCache
    distribution: Distribution | None = None
    leadership: Leadership | None = None


def get_services(request: Request) -> Services:
    return request.app.state.services


def socket_services(websocket: WebSocket) -> Services:
    return websocket.app.state.services


ServicesDep = Annotated[Services, Depends(get_services)]
