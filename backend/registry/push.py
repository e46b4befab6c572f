"""Tell connected robots which model to run: `assign_model` messages over their websocket.

Sent right after a rollout change is committed, after `welcome` when a robot (re)connects with a
different version than assigned, and by a reconcile loop that resends an assignment a robot has
not switched to (this also carries rollbacks made by the worker's automatic check).

A robot whose assigned model needs more than keypoints also gets its mode's keypoints-only
fallback (`fallback: true`, backend.registry.capability) after every `welcome` and whenever that
fallback changes (a new one promoted, the assigned model changed); the reconcile loop notices
changes made elsewhere.
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool

from backend.models.registry import ModelVersion
from backend.models.robots import Robot
from backend.realtime.robot_link import RobotConnection
from backend.realtime.robot_registry import RobotRegistry
from backend.registry.capability import fallback_for
from vigil.protocol import ModelAssignment

log = logging.getLogger(__name__)
DOWNLOAD_PATH = "/api/robot/models/{version}/file"


def assignment_for(
    model: ModelVersion, base_url: str, shadow: bool, fallback: bool = False
) -> ModelAssignment:
    return ModelAssignment(
        version=model.version,
        url=base_url + DOWNLOAD_PATH.format(version=model.version),
        sha256=model.sha256,
        manifest=model.manifest,
        shadow=shadow,
        fallback=fallback,
    )


def runs_assigned(assigned: ModelVersion, running: str | None, running_sha256: str | None) -> bool:
    """The robot says it runs the assigned version, and no other file under that name (an
    agent that reports no sha256 is taken at its word: resending would not change it)."""
    if assigned.version != running:
        return False
    return running_sha256 is None or running_sha256 == assigned.sha256


@dataclass
class Sent:
    """What this process sent to each robot."""

    #: robot id -> (assigned version, monotonic time) of the last push
    assignments: dict[str, tuple[str | None, float]] = field(default_factory=dict)
    #: robot id -> shadow version sent on its current connection (an agent drops its shadow
    #: model when it reconnects, so this is what each connected robot runs beside production)
    shadows: dict[str, str] = field(default_factory=dict)
    #: robot id -> fallback version sent on its current connection
    fallbacks: dict[str, str] = field(default_factory=dict)
    #: robot id -> (version, sha256) it last said it runs on its current connection (hello,
    #: heartbeats): newer than the stored one, which the frame writer writes later
    running: dict[str, tuple[str | None, str | None]] = field(default_factory=dict)


class AssignmentPusher:
    """Sends `assign_model` messages through each connected robot's `RobotConnection`."""

    def __init__(
        self,
        session_factory: sessionmaker[Session],
        robots: RobotRegistry,
        resend_after_s: float,
    ) -> None:
        self._session_factory = session_factory
        self._robots = robots
        self.resend_after_s = resend_after_s
        self.sent = Sent()

    def _wanted(
        self, robot_id: str
    ) -> tuple[
        ModelVersion | None, ModelVersion | None, ModelVersion | None, str | None, str | None
    ]:
        """(assigned, shadow, fallback, running version, running sha256) of a robot."""
        with self._session_factory() as session:
            robot = session.get(Robot, robot_id)
            if robot is None:
                return None, None, None, None, None
            assigned = (
                session.get(ModelVersion, robot.assigned_model_id)
                if robot.assigned_model_id
                else None
            )
            shadow = (
                session.get(ModelVersion, robot.shadow_model_id) if robot.shadow_model_id else None
            )
            fallback = fallback_for(session, assigned)
            session.expunge_all()
            return (
                assigned,
                shadow,
                fallback,
                robot.running_model_version,
                robot.running_model_sha256,
            )

    def _link(self, robot_id: str) -> RobotConnection | None:
        link = self._robots.socket(robot_id)
        return None if link is None or link.closed else link

    async def push_to_robot(
        self,
        robot_id: str,
        force: bool = True,
        reported: tuple[str | None, str | None] | None = None,
    ) -> bool:
        """Send the robot its assignment(s) if it is connected here; True if anything was sent.
        `reported`: what the robot runs (version, sha256) as its hello said, newer than the
        stored one (the frame writer stores it after the welcome)."""
        link = self._link(robot_id)
        if link is None:
            return False
        assigned, shadow, fallback, running, running_sha256 = await run_in_threadpool(
            self._wanted, robot_id
        )
        if reported is None:
            reported = self.sent.running.get(robot_id)
        if reported is not None:
            running, running_sha256 = reported
        shadows, fallbacks = self.sent.shadows, self.sent.fallbacks
        # A withdrawn shadow deployment: the production assignment also stops the shadow model
        # (protocol 1 extension). Without a production assignment the robot drops it on
        # reconnect.
        stop_shadow = force and shadow is None and robot_id in shadows
        messages = []
        if assigned is not None and (force or not runs_assigned(assigned, running, running_sha256)):
            production = assignment_for(assigned, link.base_url, shadow=False)
            if stop_shadow:
                production = production.model_copy(update={"stop_shadow": True})
            messages.append(production)
        if shadow is not None and force:
            messages.append(assignment_for(shadow, link.base_url, shadow=True))
        if fallback is None:
            fallbacks.pop(robot_id, None)  # nothing to withdraw: the robot keeps it unused
        elif force or fallbacks.get(robot_id) != fallback.version:
            messages.append(assignment_for(fallback, link.base_url, shadow=False, fallback=True))
        for message in messages:
            if not await link.send(message):  # it gets the assignment when it is back
                log.info("robot %s disconnected before its assignment was sent", robot_id)
                return False
            log.info(
                "assigned %s%s to robot %s",
                message.version,
                " (shadow)"
                if message.shadow
                else " (shadow stopped)"
                if message.stop_shadow
                else " (fallback)"
                if message.fallback
                else "",
                robot_id,
            )
            if message.fallback:
                fallbacks[robot_id] = message.version
            elif message.shadow:
                shadows[robot_id] = message.version
            elif message.stop_shadow:
                shadows.pop(robot_id, None)
        self.sent.assignments[robot_id] = (assigned.version if assigned else None, time.monotonic())
        return bool(messages)

    async def push_to_robots(self, robot_ids: list[str]) -> None:
        for robot_id in robot_ids:
            await self.push_to_robot(robot_id)

    async def on_robot_connected(
        self, robot_id: str, reported: tuple[str | None, str | None] | None = None
    ) -> None:
        """Called by the robot socket after `welcome`: send what the robot should run, if it
        differs from what it reported in hello (`reported`: running version and sha256, which
        the frame writer may not have stored yet), or a shadow model is assigned."""
        self.sent.shadows.pop(robot_id, None)  # the agent dropped its shadow model on welcome
        self.sent.fallbacks.pop(robot_id, None)  # sent again after every welcome
        if reported is not None:
            self.sent.running[robot_id] = reported
        else:
            self.sent.running.pop(robot_id, None)
        assigned, shadow, fallback, running, running_sha256 = await run_in_threadpool(
            self._wanted, robot_id
        )
        if reported is not None:
            running, running_sha256 = reported
        if shadow is not None:
            await self.push_to_robot(robot_id, force=True, reported=reported)
        elif (
            assigned is not None and not runs_assigned(assigned, running, running_sha256)
        ) or fallback is not None:
            await self.push_to_robot(robot_id, force=False, reported=reported)

    def robot_reported(self, robot_id: str, version: str, sha256: str | None) -> None:
        """A connected robot's heartbeat named the model it runs now."""
        self.sent.running[robot_id] = (version, sha256)

    def _assigned(self) -> list[tuple[str, str, bool, str | None]]:
        """(robot, assigned version, whether it runs it, fallback version) of robots with a
        model; what a robot connected here last reported counts over what is stored."""
        cache: dict = {}
        with self._session_factory() as session:
            rows = session.execute(
                select(
                    Robot.id, ModelVersion, Robot.running_model_version, Robot.running_model_sha256
                ).join(ModelVersion, ModelVersion.id == Robot.assigned_model_id)
            ).all()
            out = []
            for robot_id, model, running, running_sha256 in rows:
                running, running_sha256 = self.sent.running.get(robot_id, (running, running_sha256))
                fallback = fallback_for(session, model, cache)
                out.append(
                    (
                        robot_id,
                        model.version,
                        runs_assigned(model, running, running_sha256),
                        fallback.version if fallback else None,
                    )
                )
            return out

    async def reconcile(self) -> list[str]:
        """Resend to connected robots that still do not run their assigned version."""
        pushed = []
        for robot_id, version, runs, fallback in await run_in_threadpool(self._assigned):
            if self._link(robot_id) is None:
                continue
            new_fallback = fallback is not None and self.sent.fallbacks.get(robot_id) != fallback
            if runs and not new_fallback:
                continue
            last = self.sent.assignments.get(robot_id)
            recent = (
                last and last[0] == version and time.monotonic() - last[1] < self.resend_after_s
            )
            if recent and not new_fallback:
                continue
            if await self.push_to_robot(robot_id, force=False):
                pushed.append(robot_id)
        return pushed

    async def reconcile_forever(self, period_s: float = 2.0) -> None:
        while True:
            await asyncio.sleep(period_s)
            try:
                await self.reconcile()
            except Exception:
                log.exception("assignment reconcile failed")
