"""One robot: its transports flow through the pipeline into the outbox while the link streams
the outbox to the backend, the local alarm watches for unacknowledged Emergencies and model
assignments are fetched and swapped in."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import shlex
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from robot_agent.alarm import LocalAlarm
from robot_agent.backoff import Backoff
from robot_agent.behaviour import Behaviour, BehaviourChange
from robot_agent.client import LinkFatal, RobotLink
from robot_agent.local_command import BehaviourHook, LocalCommandServer
from robot_agent.models import ModelRefused, fetch_model, forget_running, remember_running
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from vigil.inputs import is_keypoints_only
from vigil.observation import Observation
from vigil.protocol import (
    AlarmAcknowledged,
    AlarmResolved,
    BehaviourChanged,
    EmergencyReset,
    ModelAssignment,
    Welcome,
)

log = logging.getLogger(__name__)


@dataclass
class TransportPlan:
    """One transport: its observations, and what the backend should show about it."""

    observations: Iterable[Observation]
    patient: str | None = None
    location: str | None = None
    materialise: bool = False  # generate all observations in a thread before the transport starts
    fps: float | None = None  # the source's real frame rate, when it knows it
    #: What a GENERATED transport was made to contain (its ground truth), shown in the log.
    generated_events: tuple[str, ...] = ()


def transport_started(robot_id: str, transport_id: str, plan: TransportPlan) -> str:
    """The log line of a transport's start; a GENERATED one names its events (bench/demo_hour.py
    counts the fleet's falls from these lines)."""
    events = plan.generated_events
    return (
        f"robot {robot_id}: transport {transport_id} started (patient {plan.patient or 'unknown'}"
        f", {plan.location or 'no location'})"
        + (f"; GENERATED events: {', '.join(events)}" if events else "")
    )


@dataclass
class AgentOptions:
    url: str | list[str]  # several: backend replicas, tried in turn
    heartbeat_s: float = 5.0
    batch_frames: int = 100
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 15.0
    alarm_after_s: float = 3.0
    alarm_hook: str | None = None
    pause_hold_s: float = 2.0
    degraded_action: str = "stop"
    patient_unseen_s: float = 3.0
    local_socket: Path | None = None
    speed: float = 1.0  # pace observations at their timestamps / speed; 0: as fast as possible
    exit_when_done: bool = False


class RobotAgent:
    def __init__(
        self,
        robot_id: str,
        token: str,
        pipeline: Pipeline,
        transports: Iterator[TransportPlan],
        options: AgentOptions,
        models_dir: Path,
    ) -> None:
        self.robot_id = robot_id
        self.token = token
        self.pipeline = pipeline
        self.outbox: Outbox = pipeline.outbox
        self.transports = transports
        self.options = options
        self.models_dir = models_dir
        self.link = RobotLink(
            options.url,
            robot_id,
            token,
            self.outbox,
            running_model=lambda: pipeline.running_model,
            inputs=pipeline.detector.available_inputs,
            on_assignment=self.on_assignment,
            on_welcome=self._on_welcome,
            loaded_models=pipeline.loaded_models,
            heartbeat_s=options.heartbeat_s,
            batch_frames=options.batch_frames,
            backoff=Backoff(options.backoff_initial_s, options.backoff_max_s),
            on_alarm=self.on_alarm,
        )
        self.alarm = LocalAlarm(
            robot_id,
            self.outbox,
            problem=lambda: self.link.last_problem,
            transport=lambda: pipeline.transport_id,
            after_s=options.alarm_after_s,
            hook=options.alarm_hook,
        )
        pipeline.behaviour = self.behaviour = Behaviour(
            pipeline.mode,
            options.pause_hold_s,
            options.degraded_action,
            options.patient_unseen_s,
            robot_id,
        )
        self.behaviour.on_reset = self._report_reset
        self.behaviour.listeners.append(self._report_behaviour)
        self.local = (
            LocalCommandServer(options.local_socket, self.behaviour)
            if options.local_socket is not None
            else None
        )
        if options.alarm_hook:
            self.behaviour.listeners.append(
                BehaviourHook(shlex.split(options.alarm_hook), robot_id)
            )
        self.frames = 0
        self.source_done = asyncio.Event()
        # Called once the source ended and when the agent stops (e.g. finish a recorded bag).
        self.on_source_done: list[Callable[[], None]] = []
        self._fetching: set[str] = set()
        # The registry's sha256 of versions, as the backend told (welcome, assignments).
        self.registry_sha256: dict[str, str] = {}

    # --- models ------------------------------------------------------------------------------
    def _on_welcome(self, welcome: Welcome) -> None:
        # A shadow model lasts one connection: the backend sends it again after each welcome
        # while it is still assigned, and has no message to withdraw it.
        self.pipeline.set_shadow(None)
        if welcome.model_sha256 is not None:  # an older backend does not say
            self.check_against_registry(welcome.model_sha256)

    def check_against_registry(self, registry: dict[str, str]) -> None:
        """Refuse a model this robot runs whose file is not the registry's (the file and its
        local manifest may both have been replaced): it stops deciding at once, the fallback
        decides if its own file verifies, and the nurse board shows why. A version the registry
        does not know (a model given with --model-dir) is left alone."""
        self.registry_sha256.update(registry)
        registry = self.registry_sha256
        fallback = self.pipeline.fallback
        fallback_ok = fallback is not None and registry.get(fallback.version) == fallback.sha256
        if fallback is not None and not fallback_ok and fallback.version in registry:
            reason = _mismatch(fallback.version, fallback.sha256, registry[fallback.version])
            log.error("robot %s: keypoints-only fallback %s", self.robot_id, reason)
            if self.pipeline.classifier is fallback:
                self._refuse_running(reason, None)
            self.pipeline.set_fallback(None)
            self.link.model_error = reason[:500]
        classifier = self.pipeline.classifier
        if classifier is None or classifier.version not in registry:
            return
        if classifier.sha256 != registry[classifier.version]:
            reason = _mismatch(classifier.version, classifier.sha256, registry[classifier.version])
            self._refuse_running(reason, fallback if fallback_ok else None)

    def _refuse_running(self, reason: str, replacement) -> None:
        version = self.pipeline.running_model or "-"
        self.pipeline.refuse_model(version, reason, replacement)
        forget_running(self.models_dir)  # a restart must not start with it either
        self.link.model_error = reason[:500]
        self.link.heartbeat_now()

    async def on_assignment(self, assignment: ModelAssignment) -> None:
        if assignment.stop_shadow and self.pipeline.shadow is not None:
            # The backend withdrew the shadow deployment (protocol 1 extension).
            self.pipeline.set_shadow(None)
            self.link.heartbeat_now()
        running = self.pipeline.running_model
        # A model already here with the assigned version runs on only if its file is the one
        # the registry holds (the assignment's sha256); else it is refused and fetched again.
        if assignment.fallback:
            fallback = self.pipeline.fallback
            if fallback is not None and fallback.version == assignment.version:
                if fallback.sha256 == assignment.sha256:
                    return
                self.check_against_registry({assignment.version: assignment.sha256})
        elif assignment.shadow:
            shadow = self.pipeline.shadow
            if shadow is not None and shadow.version == assignment.version:
                if shadow.sha256 == assignment.sha256:
                    return
                self.pipeline.set_shadow(None)
        elif assignment.version == running:
            if self.pipeline.classifier.sha256 == assignment.sha256:
                return
            self.check_against_registry({assignment.version: assignment.sha256})
        kind = "fallback" if assignment.fallback else "shadow" if assignment.shadow else "model"
        key = f"{kind}:{assignment.version}"
        if key in self._fetching:
            return
        self._fetching.add(key)
        role = {"fallback": "keypoints-only fallback", "shadow": "shadow model"}.get(kind, "model")
        log.info(
            "robot %s: backend assigned %s %s; fetching it", self.robot_id, role, assignment.version
        )
        try:
            classifier = await asyncio.to_thread(
                fetch_model,
                assignment,
                self.robot_id,
                self.token,
                self.models_dir,
                self.pipeline.mode,
            )
            if assignment.fallback and not is_keypoints_only(classifier.manifest.inputs):
                raise ModelRefused(
                    f"fallback {assignment.version} needs {classifier.manifest.inputs}: a "
                    "fallback must need keypoints only"
                )
        except ModelRefused as refused:
            self.link.model_error = str(refused)[:500]
            log.error(
                "robot %s: %s; model %s keeps running",
                self.robot_id,
                refused,
                self.pipeline.running_model,
            )
            self.link.heartbeat_now()
            return
        finally:
            self._fetching.discard(key)
        self.registry_sha256[assignment.version] = assignment.sha256  # fetch_model checked it
        # Every swap runs on the event loop, so it happens between two frames.
        if assignment.fallback:
            self.pipeline.set_fallback(classifier)
        elif assignment.shadow:
            self.pipeline.set_shadow(classifier)
        else:
            self.pipeline.swap_model(classifier)
            remember_running(self.models_dir, assignment.version, assignment.sha256)
            self.link.model_error = None
        self.link.heartbeat_now()

    # --- the robot's behaviour --------------------------------------------------------------
    def on_alarm(self, message: AlarmAcknowledged | AlarmResolved) -> None:
        """A nurse acknowledged (help is coming) or resolved (an emergency stop is released)
        this robot's alarm: shown locally (log, local socket, hook)."""
        if isinstance(message, AlarmAcknowledged):
            self.behaviour.acknowledged(message.alarm_id, message.by, message.at)
            return
        released = None
        if message.kind == "emergency":  # a resolved Pause alarm releases no emergency stop
            released = self.behaviour.resolved(message.alarm_id, message.by, message.at)
        if released is None:
            log.info(
                "robot %s: %s alarm %d resolved by %s (no emergency stop released)",
                self.robot_id,
                message.kind,
                message.alarm_id,
                message.by,
            )

    def _report_behaviour(self, change: BehaviourChange) -> None:
        """Each behaviour change goes to the backend too (fleet page, the alarm's audit),
        queued in the outbox behind the frames that caused it: never lost while offline."""
        if change.event != "behaviour":
            return  # "help is coming" came from the backend: nothing to tell it
        message = BehaviourChanged(
            ts=time.time(),
            state=change.state,
            reason=change.reason[:500],
            since=change.since,
            transport_id=change.transport_id,
            alarm_id=change.alarm_id,
        )
        self.outbox.add_message(message.model_dump_json(exclude_none=True))
        self.link.notify_queued()

    def _report_reset(self, ts: float, transport_id, alarm_id, who: str) -> None:
        message = EmergencyReset(ts=ts, transport_id=transport_id, alarm_id=alarm_id, by=who)
        self.outbox.add_message(message.model_dump_json(exclude_none=True))
        self.link.notify_queued()

    # --- frames ------------------------------------------------------------------------------
    async def produce(self) -> None:
        number = 0
        # The next plan is made in a thread: preparing a generated transport takes a while.
        while (plan := await asyncio.to_thread(next, self.transports, None)) is not None:
            number += 1
            # Generated data: the whole transport is made (in a thread) before it starts, so
            # the backend never sees a transport without frames (stream stalled, robot
            # offline) while the generator works.
            made = await asyncio.to_thread(list, plan.observations) if plan.materialise else None
            transport_id = f"{self.robot_id}-{int(time.time())}-{number}"[-64:]
            self.pipeline.start_transport(
                transport_id, time.time(), plan.patient, plan.location, plan.fps
            )
            log.info("%s", transport_started(self.robot_id, transport_id, plan))
            await self._stream(plan, made)
            self.pipeline.end_transport(time.time())
            self.link.notify_queued()
            log.info(
                "robot %s: transport %s ended after %d frames in total",
                self.robot_id,
                transport_id,
                self.frames,
            )
        self._source_ended()

    def _source_ended(self) -> None:
        self.source_done.set()
        while self.on_source_done:
            self.on_source_done.pop(0)()

    async def _stream(self, plan: TransportPlan, made: list[Observation] | None) -> None:
        """A recording or camera is read frame by frame in a thread, one frame ahead: the next
        frame's pose estimation runs while this one goes through the frame path, so the robot
        keeps real time while the slower of the two fits between frames, not their sum."""
        upcoming: asyncio.Future | None = None
        if made is not None:  # made already (generated data)
            ready = iter(made)
        else:
            iterator = iter(plan.observations)
            # Submitted to the thread at once (asyncio.to_thread would wait for the next await).
            loop = asyncio.get_running_loop()
            read_next = partial(loop.run_in_executor, None, next, iterator, None)
            upcoming = read_next()
        speed = self.options.speed
        started: float | None = None
        first_ts = 0.0
        try:
            while True:
                if upcoming is None:
                    observation = next(ready, None)
                else:
                    observation = await upcoming
                    upcoming = None
                    if observation is not None:  # read the next frame while this one is processed
                        upcoming = read_next()
                if observation is None:
                    return
                if speed > 0:
                    if started is None:
                        started, first_ts = time.monotonic(), observation.timestamp
                    due = started + (observation.timestamp - first_ts) / speed
                    # Always yield, even when behind real time (a loaded machine, several
                    # robots in one process): a generated transport is made already, so without
                    # this await the link (frames, heartbeats, acks) would not run until the
                    # transport ended, and the backend would see a stalled stream and an
                    # offline robot on every transport.
                    await asyncio.sleep(max(due - time.monotonic(), 0))
                elif self.frames % 50 == 0:
                    await asyncio.sleep(0)  # let the link breathe when running flat out
                self.pipeline.process(observation)
                self.frames += 1
                self.link.notify_queued()
        finally:
            if upcoming is not None and not upcoming.done():
                upcoming.cancel()

    # --- the whole robot ---------------------------------------------------------------------
    async def run(self) -> None:
        """Until cancelled (or, with exit_when_done, until everything was acknowledged)."""
        tasks = [
            asyncio.create_task(self.link.run(), name=f"{self.robot_id}-link"),
            asyncio.create_task(self.alarm.run(), name=f"{self.robot_id}-alarm"),
            asyncio.create_task(self.produce(), name=f"{self.robot_id}-source"),
        ]
        if self.local is not None:
            await self.local.start()  # listening before the first frame is decided
        if self.options.exit_when_done:
            tasks.append(asyncio.create_task(self._until_drained(), name="drained"))
        try:
            while True:
                done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in done:
                    if task.exception() is not None:
                        raise task.exception()
                    if task.get_name() == "drained":
                        return
                tasks = [t for t in tasks if not t.done()]
        finally:
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, LinkFatal, Exception):
                    await task
            if self.local is not None:
                await self.local.close()
            while self.on_source_done:  # stopped before the source ended
                self.on_source_done.pop(0)()

    async def _until_drained(self) -> None:
        await self.source_done.wait()
        while not self.link.delivered_all():
            await asyncio.sleep(0.1)
        log.info(
            "robot %s: source ended and the backend acknowledged every frame (%d frames)",
            self.robot_id,
            self.frames,
        )


def _mismatch(version: str, actual: str, registry: str) -> str:
    return f"model {version} refused: sha256 of its file is {actual}, the registry's is {registry}"
