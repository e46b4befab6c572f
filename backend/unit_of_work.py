"""The one transaction boundary: a unit of work per request, job step or writer batch.

Nothing else in the code base commits (tests/backend/test_unit_of_work.py scans the source for
`.commit(` and `.begin(` calls elsewhere). Services take the unit's `Session` and never commit;
what must happen only once their change is durable (push an alarm to the nurse boards, send a
robot its model assignment, close a socket whose credentials were just revoked) they register
on the unit with `publish_alarm(session, alarm, serialise)`,
`push_assignments(session, robot_ids)`, `fleet_changed(session, robot_ids)` (tell the engineers'
fleet pages to reload) or `after_commit(session, hook)`. The owner of the unit
(the request dependency, the frame writer, the alarm monitor, a job) runs those effects after
the commit, in the event loop, with `run_after_commit(effects)`; nothing registered on a unit
that rolls back ever runs.

A unit may be opened in a worker thread (the writer's commit, a job) and its effects run later
in the event loop: registering only records what to do.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import AsyncIterator, Awaitable, Callable, Iterable, Iterator
from contextlib import asynccontextmanager, contextmanager
from typing import TYPE_CHECKING, Protocol

from sqlalchemy import Connection
from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool

if TYPE_CHECKING:
    from backend.models.alarms import Alarm

log = logging.getLogger(__name__)

_UNIT = "vigil.unit_of_work"

AfterCommit = Callable[[], Awaitable[None] | None]
#: The alarm domain's JSON of alarms, all of a unit's at once (one query loads what a flush
#: left unloaded of them, not one or two per alarm).
SerialiseAlarms = Callable[[Session, "list[Alarm]"], list[dict]]


class Effects(Protocol):
    """Where a committed unit's effects go (the services container in the backend)."""

    async def publish_alarm(self, alarm: dict) -> None: ...

    async def push_assignments(self, robot_ids: list[str]) -> None: ...

    # Optional (an Effects without it drops robot messages): send one message to a robot
    # connected to this process (alarm_acknowledged, alarm_resolved).
    # async def send_to_robot(self, robot_id: str, text: str) -> None: ...
    # Optional too (an Effects without it drops the news): tell the browsers that show the
    # fleet (engineers, admins) that these robots' rows or the deployments changed.
    # async def publish_fleet(self, robot_ids: list[str]) -> None: ...
    # Optional (without it each alarm goes through publish_alarm): a unit's alarms at once, in
    # their order (a flush of a hundred robots in Emergency pushes dozens).
    # async def publish_alarms(self, alarms: list[dict]) -> None: ...


class UnitOfWork:
    """One session in one transaction; `commit()` is the only commit of the code base."""

    def __init__(self, factory: sessionmaker[Session]) -> None:
        self.session = factory()
        self.session.info[_UNIT] = self
        # id -> (alarm, its serialiser); the last change of each is pushed
        self._alarms: dict[int, tuple[Alarm, SerialiseAlarms]] = {}
        self._published: list[dict] = []  # AlarmOut JSON, serialised at commit
        self._robots: list[str] = []
        self._hooks: list[AfterCommit] = []
        self._robot_messages: list[tuple[str, str]] = []  # (robot_id, message JSON)
        # None: the fleet did not change; else the robots whose rows changed (may be empty: a
        # deployment changed and no robot's target with it)
        self._fleet: list[str] | None = None
        self.committed = False
        self._effects_ran = False

    # -- what services register --------------------------------------------------------------
    def publish_alarm(self, alarm: Alarm, serialise: SerialiseAlarms) -> None:
        """Push `alarm` after the commit, as `serialise` (the alarm domain's own JSON, for all
        the unit's alarms at once) makes it at commit time: the unit of work knows no alarm
        schema."""
        self._alarms.pop(alarm.id, None)  # re-inserted: pushed in the order of last change
        self._alarms[alarm.id] = (alarm, serialise)

    def push_assignments(self, robot_ids: Iterable[str]) -> None:
        self._robots.extend(r for r in robot_ids if r not in self._robots)

    def fleet_changed(self, robot_ids: Iterable[str] = ()) -> None:
        if self._fleet is None:
            self._fleet = []
        self._fleet.extend(r for r in robot_ids if r not in self._fleet)

    def after_commit(self, hook: AfterCommit) -> None:
        self._hooks.append(hook)

    def tell_robot(self, robot_id: str, text: str) -> None:
        self._robot_messages.append((robot_id, text))

    # -- the boundary ------------------------------------------------------------------------
    def commit(self) -> None:
        self.session.flush()
        if self._alarms:
            batches: dict[SerialiseAlarms, list[Alarm]] = {}
            for alarm, serialise in self._alarms.values():
                batches.setdefault(serialise, []).append(alarm)
            made: dict[int, dict] = {}
            for serialise, alarms in batches.items():
                for alarm, out in zip(alarms, serialise(self.session, alarms), strict=True):
                    made[alarm.id] = out
            self._published = [made[alarm_id] for alarm_id in self._alarms]
        self.session.commit()
        self.committed = True

    def rollback(self) -> None:
        self.session.rollback()
        self._alarms.clear()
        self._robots.clear()
        self._hooks.clear()
        self._robot_messages.clear()
        self._fleet = None

    def close(self) -> None:
        self.session.info.pop(_UNIT, None)
        self.session.close()

    @property
    def published_alarms(self) -> list[dict]:
        """The committed alarms as pushed to browsers (AlarmOut JSON), in order of change."""
        return list(self._published)

    @property
    def assigned_robots(self) -> list[str]:
        return list(self._robots)

    def take_effects(self, other: UnitOfWork) -> None:
        """Adopt the effects of another committed unit (the writer's robot-by-robot retry)."""
        self._published.extend(other._published)
        self.push_assignments(other._robots)
        self._hooks.extend(other._hooks)
        self._robot_messages.extend(other._robot_messages)
        if other._fleet is not None:
            self.fleet_changed(other._fleet)

    async def run_after_commit(self, effects: Effects | None = None) -> None:
        """Alarms first, then assignments, the fleet's news, then the other hooks; each failure
        is logged and the rest still run (the change is committed whatever a browser or robot
        does)."""
        if not self.committed or self._effects_ran:
            return
        self._effects_ran = True
        alarms, robots, hooks = self._published, self._robots, self._hooks
        if effects is not None:
            publish_alarms = getattr(effects, "publish_alarms", None)
            if publish_alarms is not None and alarms:
                try:
                    await publish_alarms(alarms)
                except Exception:
                    log.exception("alarms %s not published", [a.get("id") for a in alarms])
            for alarm in alarms if publish_alarms is None else ():
                try:
                    await effects.publish_alarm(alarm)
                except Exception:
                    log.exception("alarm %s not published", alarm.get("id"))
            if robots:
                try:
                    await effects.push_assignments(robots)
                except Exception:
                    log.exception("assignments to %s not sent", robots)
            publish_fleet = getattr(effects, "publish_fleet", None)
            if self._fleet is not None and publish_fleet is not None:
                try:
                    await publish_fleet(list(self._fleet))
                except Exception:
                    log.exception("fleet change of %s not published", self._fleet)
            send = getattr(effects, "send_to_robot", None)
            for robot_id, text in self._robot_messages if send is not None else ():
                try:
                    await send(robot_id, text)
                except Exception:
                    log.exception("message to robot %s not sent", robot_id)
        for hook in hooks:
            try:
                result = hook()
                if inspect.isawaitable(result):
                    await result
            except Exception:
                log.exception("after-commit hook failed")

    def run_after_commit_sync(self) -> None:
        """For processes without an event loop (worker, CLI): run the plain hooks; alarms and
        assignments reach browsers and robots through the backend (reconcile loop, reload)."""
        if not self.committed or self._effects_ran:
            return
        self._effects_ran = True
        for hook in self._hooks:
            try:
                result = hook()
                if inspect.isawaitable(result):
                    result.close()  # type: ignore[union-attr]
                    log.warning("async after-commit hook dropped outside the event loop")
            except Exception:
                log.exception("after-commit hook failed")


@contextmanager
def unit_of_work(factory: sessionmaker[Session]) -> Iterator[UnitOfWork]:
    """Commit on success, roll back on error; effects are left for the caller to run."""
    unit = UnitOfWork(factory)
    try:
        yield unit
        unit.commit()
    except BaseException:
        unit.rollback()
        raise
    finally:
        unit.close()


def _commit_and_close(unit: UnitOfWork) -> None:
    try:
        unit.commit()
    finally:
        unit.close()


def _rollback_and_close(unit: UnitOfWork) -> None:
    try:
        unit.rollback()
    finally:
        unit.close()


@asynccontextmanager
async def in_event_loop(
    factory: sessionmaker[Session], effects: Effects | None
) -> AsyncIterator[UnitOfWork]:
    """A unit of work owned by async code (a request): the session's work and the commit run
    in worker threads, the effects in the event loop once committed."""
    unit = UnitOfWork(factory)
    try:
        yield unit
    except BaseException:
        await run_in_threadpool(_rollback_and_close, unit)
        raise
    await run_in_threadpool(_commit_and_close, unit)
    await unit.run_after_commit(effects)


@contextmanager
def transaction(factory: sessionmaker[Session]) -> Iterator[Session]:
    """A unit of work whose caller needs only the session (jobs, CLI, tests); plain
    after-commit hooks run once committed."""
    with unit_of_work(factory) as unit:
        yield unit.session
    unit.run_after_commit_sync()


@contextmanager
def savepoint(connection: Connection) -> Iterator[None]:
    """A step of the current transaction that an error undoes alone: the transaction stays
    usable (a lock not taken within its lock_timeout can be tried again)."""
    nested = connection.begin_nested()
    try:
        yield
    except BaseException:
        nested.rollback()
        raise
    nested.commit()


def of(session: Session) -> UnitOfWork | None:
    """The unit of work a session belongs to (None for a read-only session)."""
    return session.info.get(_UNIT)


def publish_alarm(session: Session, alarm: Alarm, serialise: SerialiseAlarms) -> None:
    """Push this alarm (as `serialise` makes it) to the boards once the session's unit
    commits. The alarm domain calls it (`backend.alarms.service.publish`)."""
    unit = of(session)
    if unit is not None:
        unit.publish_alarm(alarm, serialise)


def push_assignments(session: Session, robot_ids: Iterable[str]) -> None:
    """Send these robots their model assignment once the session's unit commits."""
    unit = of(session)
    if unit is not None:
        unit.push_assignments(robot_ids)


def fleet_changed(session: Session, robot_ids: Iterable[str] = ()) -> None:
    """Tell the fleet pages (engineers', admins') to reload once the session's unit commits:
    these robots' target or running model, or a deployment, changed."""
    unit = of(session)
    if unit is not None:
        unit.fleet_changed(robot_ids)


def tell_robot(session: Session, robot_id: str, text: str) -> None:
    """Send this message to the robot (if connected to this process) once the unit commits."""
    unit = of(session)
    if unit is not None:
        unit.tell_robot(robot_id, text)


def after_commit(session: Session, hook: AfterCommit) -> None:
    """Run `hook` once the session's unit commits (never if it rolls back)."""
    unit = of(session)
    if unit is None:
        raise RuntimeError("after_commit needs a session of a unit of work")
    unit.after_commit(hook)
