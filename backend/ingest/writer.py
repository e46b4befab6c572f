"""The per-process frame writer: gathers the messages of every robot connection and commits
them together, every `ingest_flush_ms` or as soon as `ingest_flush_frames` are waiting.

Only after the commit are the robots acknowledged (their highest committed sequence number)
and the alarms their decisions raised pushed (the effects the alarm service registered on the
flush's unit of work, `backend.unit_of_work`). If a shared transaction fails, each robot's work
is retried in its own transaction so one misbehaving robot cannot hold back the others.

While a commit is blocked (storage stalled) a watch task fails open (`backend.ingest.failopen`):
Emergencies reach the nurse board marked not yet stored, and a storage-stalled technical alarm
shows.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from dataclasses import dataclass, field
from typing import Protocol

from sqlalchemy.exc import DataError
from sqlalchemy.orm import Session, sessionmaker

from backend.alarms import queries as alarm_queries
from backend.alarms import service as alarm_service
from backend.ingest import service
from backend.ingest.context import TRAILING_PUSH_GRACE_S, IngestContext
from backend.ingest.failopen import FailOpen
from backend.ingest.received import ReceivedFrame, ReceivedFrames
from backend.ingest.stall_actions import StallActions
from backend.metrics import Metrics
from backend.models.alarms import AlarmKind, AlarmState
from backend.unit_of_work import Effects, UnitOfWork, unit_of_work
from vigil import protocol
from vigil.classes import Decision
from vigil.protocol import (
    BehaviourChanged,
    DetectionStatus,
    EmergencyReset,
    Heartbeat,
    Hello,
    TransportEnd,
    TransportStart,
)

log = logging.getLogger(__name__)

RobotWork = (
    ReceivedFrames
    | TransportStart
    | TransportEnd
    | Heartbeat
    | DetectionStatus
    | EmergencyReset
    | BehaviourChanged
    | Hello  # what a robot said at connect, stored after its welcome
)
CACHE_SECONDS = 5.0


class RejectedMessage(Exception):
    """A message the database refuses for this robot; its connection is closed with `code`."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason


class Acknowledged(Protocol):
    """What the writer needs of a robot's link (backend.realtime.robot_link.RobotConnection)."""

    robot_id: str

    async def send_ack(self, seq: int) -> None: ...

    async def reject(self, code: int, reason: str) -> None: ...


@dataclass(slots=True)
class Job:
    link: Acknowledged
    message: RobotWork
    received: float  # time.perf_counter() when the message arrived

    @property
    def frame_count(self) -> int:
        return len(self.message.frames) if isinstance(self.message, ReceivedFrames) else 0

    # Committed (and pushed to the board) without waiting for more messages to batch with it:
    # it carries an Emergency decision whose alarm is not stored yet (set by `submit`).
    urgent: bool = False

    def emergency_transports(self) -> set[str]:
        """The transports ('' for none) this message decides Emergency on."""
        if not isinstance(self.message, ReceivedFrames):
            return set()
        return {
            frame.transport_id or ""
            for frame in self.message.frames
            if frame.decision == Decision.EMERGENCY
        }


@dataclass
class Outcome:
    acks: dict[int, int] = field(default_factory=dict)  # id(link) -> highest committed seq
    stored: int = 0
    units: list[UnitOfWork] = field(default_factory=list)  # committed: their effects to run
    rejected: dict[int, RejectedMessage] = field(default_factory=dict)  # id(job) -> error
    pushed: set[int] = field(default_factory=set)  # alarm ids pushed after this commit
    held_back: dict[int, float] = field(default_factory=dict)  # alarm id -> trailing push due


class FrameWriter:
    def __init__(
        self,
        session_factory: sessionmaker[Session],
        metrics: Metrics,
        effects: Effects,
        flush_ms: float = 50,
        flush_frames: int = 500,
        max_flush_frames: int = 2_000,
        max_pending_frames: int = 20_000,
        unstored_alarm_ms: float = 300,
        storage_stall_s: float = 2.0,
        stall_actions: StallActions | None = None,
    ) -> None:
        self._session_factory = session_factory
        self._metrics = metrics
        self._effects = effects  # where alarms go: committed ones and those failing open
        self._flush_s = flush_ms / 1000
        self._flush_frames = flush_frames
        self._max_flush_frames = max(max_flush_frames, 1)
        self._pending: list[Job] = []
        self._pending_frames = 0
        self._oldest: float | None = None
        self._urgent = False  # an Emergency waits: flush without lingering
        # robot id -> (monotonic time, transports ('' for none) with an unresolved Emergency
        # alarm), as stored at the last commit that loaded the robot's alarms. A robot that
        # keeps deciding Emergency (stopped, waiting for help) folds into its stored alarm:
        # its messages need not each be a commit of their own, nor a provisional card on the
        # board when a commit is slow (a hundred such robots made a commit per message, and
        # every frame waiting 0.3 s a provisional card and a push of every fold). Trusted for
        # storage_stall_s only: during a longer stall, or after a resolve made elsewhere just
        # before it, every Emergency frame is tracked by the fail-open watch again.
        self._alarmed: dict[str, tuple[float, set[str]]] = {}
        self._alarmed_trust_s = storage_stall_s
        self._arrived = asyncio.Event()
        self._room = asyncio.Event()
        self._room.set()
        self._max_pending_frames = max_pending_frames
        self._task: asyncio.Task | None = None
        self._cache: IngestContext | None = None
        self._held_back: dict[int, float] = {}  # alarm id -> trailing push due (monotonic)
        self._cache_born = 0.0
        self.fail_open = FailOpen(unstored_alarm_ms / 1000, storage_stall_s)
        self._inflight: list[Job] = []
        self._scanned_write: list[Job] | None = None  # the blocked write _waiting_wards saw
        self._scanned_pending = 0
        self._watch: asyncio.Task | None = None
        # Nurses' actions on alarms not yet stored, applied in the commit that stores them.
        self.stall_actions = stall_actions
        self._actions_due = False
        self._actions_tried = 0.0

    # -- called by robot connections -------------------------------------------------------
    async def submit(self, link: Acknowledged, message: RobotWork, received: float) -> Job:
        """Queue a message for the next commit; waits only when the writer is far behind."""
        job = Job(link, message, received)
        emergencies = job.emergency_transports()
        unalarmed = emergencies - self._stored_emergencies(link.robot_id)
        job.urgent = bool(unalarmed)
        # Before any wait: an Emergency must reach the board even if the writer is stuck.
        self.fail_open.on_submit(job, self._known_transport, unalarmed)
        while self._pending_frames >= self._max_pending_frames:
            self._room.clear()
            await self._room.wait()
        if not self._pending:
            self._oldest = received
        self._pending.append(job)
        self._pending_frames += job.frame_count
        self._urgent = self._urgent or job.urgent
        self._arrived.set()
        return job

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name="frame-writer")
        self._watch = asyncio.create_task(self._watch_storage(), name="storage-watch")

    async def stop(self) -> None:
        """Commit what is pending, then stop."""
        if self._task is None:
            return
        if self._watch is not None:
            self._watch.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._watch
        self._task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._task
        while self._pending:
            await self._flush()

    async def _run(self) -> None:
        while True:
            await self._arrived.wait()
            self._arrived.clear()
            # Linger until the oldest message has waited flush_ms or enough frames are queued,
            # unless an Emergency decision waits.
            while self._pending and not self._urgent and self._pending_frames < self._flush_frames:
                remaining = (self._oldest or 0) + self._flush_s - time.perf_counter()
                if remaining <= 0:
                    break
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._arrived.wait(), remaining)
                self._arrived.clear()
            if self._pending or self._actions_due:
                try:
                    await self._flush()
                except Exception:  # never let the writer die: log, the robots will resend
                    log.exception("frame writer flush failed")
                if self._pending:  # what one commit did not take goes in the next, at once
                    self._arrived.set()

    # -- fail open ---------------------------------------------------------------------------
    WATCH_INTERVAL_S = 0.05

    async def _watch_storage(self) -> None:
        while True:
            await asyncio.sleep(self.WATCH_INTERVAL_S)
            try:
                for alarm in self.fail_open.due(time.perf_counter(), self._waiting_wards):
                    await self._effects.publish_alarm(alarm)
                self._poke_for_actions()
                await self._trailing_pushes()
            except Exception:  # never let the watch die
                log.exception("storage watch failed")

    async def _trailing_pushes(self) -> None:
        """Alarms whose latest folds were held back (at most one push a second) and that no
        flush pushed since: pushed once their second and the grace are up, so every board ends
        on the alarm's last decision."""
        if not self._held_back:
            return
        now = time.monotonic() - TRAILING_PUSH_GRACE_S
        due = [alarm_id for alarm_id, at in self._held_back.items() if at <= now]
        if not due:
            return
        for alarm_id in due:
            del self._held_back[alarm_id]
        unit = await asyncio.to_thread(self._publish_alarms, due)
        await unit.run_after_commit(self._effects)

    def _publish_alarms(self, alarm_ids: list[int]) -> UnitOfWork:
        with unit_of_work(self._session_factory) as unit:
            for alarm in alarm_queries.by_ids(unit.session, alarm_ids):
                alarm_service.publish(unit.session, alarm)
        return unit

    def _waiting_wards(self) -> dict[str, str | None]:
        """Robot id -> ward of every robot whose messages wait on storage (asked only while a
        write is blocked: with a thousand robots, scanning every queued message twenty times
        a second took a seventh of the backend's CPU). While one write stays blocked the queue
        only grows, and the robots returned before have their alarm: only the messages queued
        since the last call are looked at."""
        if self._scanned_write is not self._inflight:
            self._scanned_write = self._inflight
            jobs = [*self._inflight, *self._pending]
        else:
            jobs = self._pending[self._scanned_pending :]
        self._scanned_pending = len(self._pending)
        return {job.link.robot_id: getattr(job.link, "ward", None) for job in jobs}

    def _poke_for_actions(self) -> None:
        """Actions on alarms stored before them (or found in the journal at start-up) wait for
        no robot's message: a commit of their own, at most once a second, never while a
        commit is blocked."""
        now = time.perf_counter()
        if (
            self.stall_actions is not None
            and self.fail_open.write_started is None
            and now - self._actions_tried >= 1.0
            and self.stall_actions.pending()
        ):
            self._actions_tried = now
            self._actions_due = True
            self._arrived.set()

    def stalled_for(self) -> float | None:
        """Seconds the running commit has been blocked, once over storage_stall_seconds."""
        blocked = self.fail_open.stalled_for(time.perf_counter())
        return None if blocked is None else round(blocked, 3)

    def blocked_for(self) -> float | None:
        """Seconds the running commit has been blocked so far (None: no commit running)."""
        started = self.fail_open.write_started
        return None if started is None else time.perf_counter() - started

    def waiting_robots(self) -> frozenset[str]:
        """Robots with messages received but not committed yet (safe from any thread)."""
        jobs = [*self._inflight, *self._pending]
        return frozenset(job.link.robot_id for job in jobs)

    def unstored_alarms(self) -> list[dict]:
        """Alarms on the board that are not (yet) stored, for a browser's snapshot."""
        return self.fail_open.board()

    def _known_transport(self, transport_id: str):
        cache = self._cache
        return cache.transports.get(transport_id) if cache is not None else None

    def transport_owner(self, transport_id: str) -> str | None:
        """The robot a transport the writer has stored or loaded belongs to (None: not known
        here). A transport never changes robots, so this is as good as asking the database."""
        transport = self._known_transport(transport_id)
        return transport.robot_id if transport is not None else None

    def _take(self) -> list[Job]:
        """The oldest queued messages, up to max_flush_frames frames (a message without
        frames, such as a hello, counts as one; at least one message).

        A commit stays short however far behind the writer is (a thousand robots reconnecting
        at once queue a hello, a transport start and frames each): a commit blocked past
        storage_stall_seconds then means storage trouble, not one giant batch, and robots are
        acknowledged as each part commits."""
        taken = frames = cost = 0
        for job in self._pending:
            cost += max(job.frame_count, 1)
            if taken and cost > self._max_flush_frames:
                break
            taken += 1
            frames += job.frame_count
        jobs, self._pending = self._pending[:taken], self._pending[taken:]
        self._pending_frames -= frames
        self._urgent = any(job.urgent for job in self._pending)
        self._oldest = self._pending[0].received if self._pending else None
        return jobs

    async def _flush(self) -> None:
        jobs = self._take()
        self._actions_due = False
        self._room.set()
        started = time.perf_counter()
        self._inflight = jobs
        self.fail_open.on_write_start(started)
        try:
            # A provisional card on the board is replaced only by a push of its stored alarm:
            # while there is one, every fold is pushed.
            outcome = await asyncio.to_thread(self._commit, jobs, self.fail_open.any_pushed())
        finally:
            self._inflight = []
            blocked = time.perf_counter() - started
            cleared = self.fail_open.on_write_done(jobs)
        self._metrics.flush_seconds.observe(time.perf_counter() - started)
        self._metrics.flush_frames.observe(outcome.stored)
        # Committed: now tell the nurses (the stored alarms replace any pushed unstored), then
        # the robots.
        for unit in outcome.units:
            await unit.run_after_commit(self._effects)
        for alarm_id in outcome.pushed:
            self._held_back.pop(alarm_id, None)
        for alarm_id, due in outcome.held_back.items():
            self._held_back.setdefault(alarm_id, due)
        self._metrics.frames_ingested.inc(outcome.stored)
        acked: dict[int, Acknowledged] = {}
        now = time.perf_counter()
        for job in jobs:
            error = outcome.rejected.get(id(job))
            if error is not None:
                await job.link.reject(error.code, error.reason)
                continue
            if id(job.link) in outcome.acks:
                acked[id(job.link)] = job.link
                self._metrics.ack_latency.observe(now - job.received)
        for key, link in acked.items():
            await link.send_ack(outcome.acks[key])
        if cleared:  # storage recovered: keep the outage in the audit trail, clear the cards
            try:
                unit = await asyncio.to_thread(self._record_stall, cleared, blocked)
            except Exception:
                log.exception("storage_stalled alarms not stored; pushed as resolved only")
                for alarm in cleared:
                    await self._effects.publish_alarm(alarm)
            else:
                await unit.run_after_commit(self._effects)

    def _record_stall(self, cleared: list[dict], blocked_s: float) -> UnitOfWork:
        with unit_of_work(self._session_factory) as unit:
            self.fail_open.record(unit.session, cleared, blocked_s)
        return unit

    # -- in a worker thread ----------------------------------------------------------------
    def _cached_context(self) -> IngestContext:
        """Robot, transport and video rows are kept between flushes (this writer is what
        changes them), dropped every CACHE_SECONDS to see changes made elsewhere (another
        replica, a revoked token) and after any failed flush."""
        now = time.monotonic()
        if self._cache is None or now - self._cache_born > CACHE_SECONDS:
            self._cache, self._cache_born = IngestContext(), now
        return self._cache

    def _commit(self, jobs: list[Job], push_every_fold: bool = False) -> Outcome:
        try:
            context = self._cached_context()
            context.push_every_fold = push_every_fold
            settled: list[str] = []
            with unit_of_work(self._session_factory) as unit:
                outcome = self._apply(unit.session, jobs, context)
                if self.stall_actions is not None:
                    settled = self.stall_actions.apply(unit.session)
            outcome.units.append(unit)
            outcome.pushed, outcome.held_back = context.pushed, context.held_back
            self._remember_alarmed(context)
            self._cache = context.detach()
            if self.stall_actions is not None:
                self.stall_actions.done(settled)
            return outcome
        except RejectedMessage:
            self._cache = None
            self._alarmed = {}
        except Exception as error:
            self._cache = None
            self._alarmed = {}
            log.warning("shared ingest transaction failed (%s); retrying robot by robot", error)
        outcome = Outcome()
        by_link: dict[int, list[Job]] = {}
        for job in jobs:
            by_link.setdefault(id(job.link), []).append(job)
        for link_jobs in by_link.values():
            try:
                with unit_of_work(self._session_factory) as unit:
                    single = self._apply(unit.session, link_jobs, IngestContext())
            except RejectedMessage as error:
                for job in link_jobs:
                    outcome.rejected[id(job)] = error
                continue
            except Exception as error:
                if _unstorable(error):  # e.g. a NUL byte in a text field on PostgreSQL
                    reason = f"value cannot be stored: {str(error).splitlines()[0]}"
                    for job in link_jobs:
                        outcome.rejected[id(job)] = RejectedMessage(
                            protocol.CLOSE_BAD_MESSAGE, reason
                        )
                    continue
                log.exception("ingest of robot %s failed", link_jobs[0].link.robot_id)
                failure = RejectedMessage(protocol.CLOSE_INTERNAL_ERROR, f"not stored: {error}")
                for job in link_jobs:
                    outcome.rejected[id(job)] = failure
                continue
            outcome.acks.update(single.acks)
            outcome.stored += single.stored
            outcome.units.append(unit)
        return outcome

    def _remember_alarmed(self, context: IngestContext) -> None:
        """The robots whose alarms this commit loaded: their stored unresolved Emergencies."""
        now = time.monotonic()
        alarmed: dict[str, tuple[float, set[str]]] = {r: (now, set()) for r in context.alarming}
        for (robot_id, key, kind), alarm in context.open_alarms.items():
            if kind == AlarmKind.EMERGENCY and alarm.state != AlarmState.RESOLVED:
                alarmed.setdefault(robot_id, (now, set()))[1].add(key)
        self._alarmed.update(alarmed)

    def _stored_emergencies(self, robot_id: str) -> set[str]:
        """The robot's transports known to have a stored unresolved Emergency alarm."""
        entry = self._alarmed.get(robot_id)
        if entry is None or time.monotonic() - entry[0] > self._alarmed_trust_s:
            return set()
        return entry[1]

    def _apply(self, session: Session, jobs: list[Job], context: IngestContext) -> Outcome:
        outcome = Outcome()
        streams: set[tuple[str, str | None]] = set()
        alarming: set[str] = set()
        for job in jobs:
            robot_id = job.link.robot_id
            if isinstance(job.message, ReceivedFrames):
                for f in job.message.frames:
                    streams.add((robot_id, f.transport_id))
                    if f.decision in service.ALARM_KIND_OF_DECISION:
                        alarming.add(robot_id)
            else:
                streams.add((robot_id, None))
                if isinstance(job.message, DetectionStatus) and job.message.transport_id:
                    streams.add((robot_id, job.message.transport_id))
        context.preload(session, streams, alarming)
        # Consecutive frame batches of one connection become one store_frames call.
        run: list[ReceivedFrame] = []
        run_link: Acknowledged | None = None

        def store_run() -> None:
            nonlocal run, run_link
            if run_link is None:
                return
            robot = self._robot(context, run_link.robot_id)
            try:
                result = service.store_frames(session, robot, run, context)
            except service.TransportNotOwned as error:
                raise _refused(error) from None
            if result.highest_seq is not None:
                key = id(run_link)
                outcome.acks[key] = max(outcome.acks.get(key, -1), result.highest_seq)
            run, run_link = [], None

        for job in sorted(jobs, key=lambda j: id(j.link)):  # stable: keeps each robot's order
            message = job.message
            if isinstance(message, ReceivedFrames):
                if run_link is not None and run_link is not job.link:
                    store_run()
                run_link = job.link
                run.extend(message.frames)
                continue
            store_run()
            robot = self._robot(context, job.link.robot_id)
            if isinstance(message, TransportStart):
                try:
                    transport = service.start_transport(session, robot, message)
                except ValueError as error:
                    raise _refused(error) from None
                context.transports[transport.id] = transport
            elif isinstance(message, TransportEnd):
                service.end_transport(session, robot, message)
            elif isinstance(message, Hello):
                service.apply_hello(robot, message)
            elif isinstance(message, Heartbeat):
                robot.last_seen_at = service.utcnow()
                if message.running_model is not None:
                    robot.running_model_version = message.running_model
                    robot.running_model_sha256 = message.running_sha256
                    robot.running_model_changed = True
                if message.model_error:
                    log.warning("robot %s refused a model: %s", robot.id, message.model_error)
            elif isinstance(message, DetectionStatus):
                # In stream order: the frames before it (this flush's included) are stored.
                robot.last_seen_at = service.utcnow()
                try:
                    changed = service.apply_detection_status(session, robot, message, context)
                except ValueError as error:
                    raise _refused(error) from None
                if changed:
                    robot.fleet_news = True  # the row's "detection degraded" pill
                    log.warning(
                        "robot %s: detection %s: %s",
                        robot.id,
                        "degraded" if message.degraded else "recovered",
                        message.reason or ", ".join(message.missing_inputs),
                    )
            elif isinstance(message, BehaviourChanged):
                service.apply_behaviour(robot, message)
                alarm_service.robot_behaviour(session, robot.id, message)
            elif isinstance(message, EmergencyReset):
                audited = alarm_service.robot_reset(session, robot.id, message)
                log.warning(
                    "robot %s: emergency stop reset on the robot (%s)%s",
                    robot.id,
                    message.by,
                    f", audited on alarm {audited.id}"
                    if audited
                    else ", no Emergency alarm to audit it on",
                )
        store_run()
        outcome.stored = context.flush_rows(session)
        context.write_back(session)
        session.flush()
        return outcome  # the alarms changed are pushed after the commit (alarms.service)

    @staticmethod
    def _robot(context: IngestContext, robot_id: str):
        robot = context.robots.get(robot_id)
        if robot is None or robot.token_hash is None:
            raise RejectedMessage(protocol.CLOSE_UNAUTHORIZED, "robot token revoked")
        return robot


def _refused(error: ValueError) -> RejectedMessage:
    """A message the service refused: another robot's transport (4403), else a bad one (4400)."""
    if isinstance(error, service.TransportNotOwned):
        return RejectedMessage(protocol.CLOSE_FORBIDDEN, str(error))
    return RejectedMessage(protocol.CLOSE_BAD_MESSAGE, str(error))


def _unstorable(error: Exception) -> bool:
    """A value the database refuses (SQLAlchemy's DataError, or the driver's own from COPY)."""
    if isinstance(error, DataError):
        return True
    return any(cls.__name__ == "DataError" for cls in type(error).__mro__)
