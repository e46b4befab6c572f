"""The alarm monitor: a task in the backend lifespan that, every `monitor_interval_s`,

- raises technical alarms for transports under way whose robot fell silent (robot offline),
  whose frame stream stopped while the robot still talks (stream stalled), or whose frames flow
  but have not shown the patient for `patient_unseen_seconds` (patient not seen: the robot lost
  its patient, or never found them; only frames stored after the last one with the patient
  say so, so a stream that is merely behind is a stalled stream, not a lost patient), one per
  outage; a robot whose messages wait in a frame writer, this replica's or another's (storage
  behind or stalled), is none of them;
- clears (resolves, as the system, transition `clear`) such an alarm, open or acknowledged,
  once its cause ended: the robot talks again, frames flow again, the patient is seen again,
  or the transport ended.
  Technical alarms are not latching (IEC 60601-1-8 lets a technical alarm end with its
  condition); the alarm and its audit trail stay in the history and the shift handover;
- escalates an open Emergency not acknowledged within the ward's escalation time, and moves
  one still unacknowledged an escalation time after the last level to "missed: needs review";
- escalates a missed Emergency on to the ward's further responders (`missed_escalation_chain`,
  per ward: charge nurse, then the rapid-response team), one each `missed_escalation_seconds`,
  so a fall nobody answered is never left alone;
- re-alarms an acknowledged alarm not resolved within `realarm_minutes`.

Each change is committed, then pushed like any other alarm change.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Collection
from datetime import datetime, timedelta

from sqlalchemy import Row
from sqlalchemy.orm import Session, sessionmaker

from backend.alarms import queries, service
from backend.models._types import utcnow
from backend.models.alarms import Alarm, AlarmKind, AlarmState
from backend.realtime.hub import Viewer
from backend.settings import Settings
from backend.unit_of_work import Effects, UnitOfWork, unit_of_work

log = logging.getLogger(__name__)
#: The technical alarms the monitor raises, and clears once their cause ended.
OUTAGE_KINDS = (AlarmKind.ROBOT_OFFLINE, AlarmKind.STREAM_STALLED, AlarmKind.PATIENT_NOT_SEEN)


class AlarmMonitor:
    def __init__(
        self,
        session_factory: sessionmaker[Session],
        settings: Settings,
        effects: Effects,
        waiting_robots: Callable[[], Collection[str]] = frozenset,
        waiting_elsewhere: Callable[[], Awaitable[Collection[str]]] | None = None,
        viewers: Callable[[], list[Viewer]] = list,
    ) -> None:
        self._session_factory = session_factory
        self._settings = settings
        self._effects = effects
        # Robots whose messages arrived but are not stored yet: their stored last_seen_at and
        # last_frame_at are stale because storage is, not because the robot fell silent.
        self._waiting_robots = waiting_robots
        # The same on the other replicas (backend.ingest.waiting), asked once per pass.
        self._waiting_elsewhere = waiting_elsewhere
        # Who has a board open: an escalation's audit entry names them.
        self._viewers = viewers
        self._task: asyncio.Task | None = None

    def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name="alarm-monitor")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(self._settings.monitor_interval_s)
            try:
                await self.tick()
            except Exception:
                log.exception("alarm monitor pass failed")

    async def tick(self, now: datetime | None = None) -> list[dict]:
        elsewhere = await self._waiting_elsewhere() if self._waiting_elsewhere else frozenset()
        unit = await asyncio.to_thread(
            self._check, now or utcnow(), self._viewers(), frozenset(elsewhere)
        )
        await unit.run_after_commit(self._effects)
        return unit.published_alarms

    def check(self, now: datetime, viewers: list[Viewer] | None = None) -> list[dict]:
        """One pass in one transaction; returns the changed alarms as pushed to browsers."""
        return self._check(now, viewers).published_alarms

    def _check(
        self,
        now: datetime,
        viewers: list[Viewer] | None = None,
        waiting_elsewhere: frozenset[str] = frozenset(),
    ) -> UnitOfWork:
        """One pass in one unit of work; the alarm service registers each change on it."""
        with unit_of_work(self._session_factory) as unit:
            session = unit.session
            self._cleared(session, now)
            self._technical(session, now, waiting_elsewhere)
            self._escalations(session, now, viewers or [])
            self._missed_escalations(session, now)
            self._realarms(session, now)
        return unit

    def _technical(
        self, session: Session, now: datetime, waiting_elsewhere: frozenset[str] = frozenset()
    ) -> list[Alarm]:
        settings = self._settings
        waiting = waiting_elsewhere | frozenset(self._waiting_robots())
        outages = []
        for transport, robot in queries.active_transports(session):
            if robot.id in waiting:
                continue
            last_seen = robot.last_seen_at
            last_frame = transport.last_frame_at or transport.started_at
            if last_seen is None or now - last_seen > timedelta(
                seconds=settings.robot_offline_seconds
            ):
                kind, silent_since = AlarmKind.ROBOT_OFFLINE, last_seen or transport.started_at
            elif now - last_frame > timedelta(seconds=settings.stream_stall_seconds):
                kind, silent_since = AlarmKind.STREAM_STALLED, last_frame
            elif (
                transport.last_frame_at is not None
                # frames came after the last one with the patient: a stream that is behind,
                # every frame it brought showing the patient, is not a patient lost
                and transport.last_frame_at
                > (last_patient := transport.last_patient_at or transport.started_at)
                and now - last_patient > timedelta(seconds=settings.patient_unseen_seconds)
            ):
                kind, silent_since = AlarmKind.PATIENT_NOT_SEEN, last_patient
            else:
                continue
            outages.append((transport, robot, kind, silent_since))
        alarmed = queries.outages_with_an_alarm(
            session, [(r.id, t.id, kind, since) for t, r, kind, since in outages]
        )
        raised = []
        for transport, robot, kind, _ in outages:
            if (robot.id, transport.id, kind) in alarmed:
                continue  # this outage already has its alarm
            evidence = service.DecisionEvidence(seq=robot.last_seq, ts=None)
            # No unresolved alarm of this outage: the query above saw every one.
            alarm = service.open_alarm(session, robot, transport, kind, evidence)
            log.warning("%s: robot %s, transport %s", kind.value, robot.id, transport.id)
            raised.append(alarm)
        return raised

    def _cleared(self, session: Session, now: datetime) -> list[Alarm]:
        """Clear the robot_offline / stream_stalled / patient_not_seen alarms whose cause ended."""
        reasons = {
            outage.alarm_id: reason
            for outage in queries.unresolved_outages(session, OUTAGE_KINDS)
            if (reason := self._outage_over(outage, now)) is not None
        }
        claimed = queries.claim(session, list(reasons))
        return [
            service.clear(session, a, now, reasons[a.id])
            for a in claimed
            if a.state in (AlarmState.OPEN, AlarmState.ACKNOWLEDGED)
        ]

    def _outage_over(self, outage: Row, now: datetime) -> str | None:
        """Why this robot_offline / stream_stalled / patient_not_seen alarm's cause ended, or
        None if it did not (`outage`: a row of `queries.unresolved_outages`). Only what the
        robot sent after the alarm was raised counts."""
        settings = self._settings
        if outage.ended_at is not None:
            return "cleared: transport ended"

        def recent(at: datetime | None, within_s: float) -> bool:
            return (
                at is not None and at > outage.raised_at and now - at <= timedelta(seconds=within_s)
            )

        if outage.kind == AlarmKind.PATIENT_NOT_SEEN:
            seen = recent(outage.last_patient_at, settings.patient_unseen_seconds)
            return "cleared: patient in view again" if seen else None
        if recent(outage.last_frame_at, settings.stream_stall_seconds):
            return "cleared: frames flowing again"
        if outage.kind == AlarmKind.ROBOT_OFFLINE and recent(
            outage.last_seen_at, settings.robot_offline_seconds
        ):
            return "cleared: robot talking again"
        return None

    def _escalations(self, session: Session, now: datetime, viewers: list[Viewer]) -> list[Alarm]:
        def due(alarm: Alarm | Row) -> bool:
            if alarm.state != AlarmState.OPEN:
                return False
            wait = timedelta(seconds=self._settings.escalation_seconds_for(alarm.ward))
            return now - (alarm.escalated_at or alarm.raised_at) >= wait

        def last_level(alarm: Alarm) -> bool:
            return alarm.escalation_level >= self._settings.escalation_max_level

        candidates = [a.id for a in queries.open_emergencies(session) if due(a)]
        claimed = [a for a in queries.claim(session, candidates) if due(a)]
        names = queries.viewer_names(session, [v.user_id for v in viewers])
        return [
            service.miss(session, a, now)
            if last_level(a)
            else service.escalate(
                session, a, now, [names[v.user_id] for v in viewers if v.can_see(a.ward)]
            )
            for a in claimed
        ]

    def _missed_escalations(self, session: Session, now: datetime) -> list[Alarm]:
        """A missed Emergency is never left alone: each `missed_escalation_seconds` it goes on
        to the next of its ward's responders, until the chain ends."""
        wait = timedelta(seconds=self._settings.missed_escalation_seconds)

        def next_responder(alarm: Alarm | Row) -> str | None:
            if (
                alarm.state != AlarmState.MISSED
                or now - (alarm.escalated_at or alarm.raised_at) < wait
            ):
                return None
            chain = self._settings.missed_escalation_chain_for(alarm.ward)
            if alarm.escalated_to is None:
                return chain[0] if chain else None
            if alarm.escalated_to not in chain:
                return None  # the chain was changed under it: do not start it over
            reached = chain.index(alarm.escalated_to) + 1
            return chain[reached] if reached < len(chain) else None

        candidates = [a.id for a in queries.missed_emergencies(session) if next_responder(a)]
        changed = []
        for alarm in queries.claim(session, candidates):
            responder = next_responder(alarm)
            if responder:
                changed.append(service.escalate_missed(session, alarm, now, responder))
        return changed

    def _realarms(self, session: Session, now: datetime) -> list[Alarm]:
        wait = timedelta(minutes=self._settings.realarm_minutes)

        def due(alarm: Alarm | Row) -> bool:
            if alarm.state != AlarmState.ACKNOWLEDGED:
                return False
            return now - (alarm.realarmed_at or alarm.acknowledged_at or alarm.updated_at) >= wait

        candidates = [a.id for a in queries.acknowledged(session) if due(a)]
        return [
            service.realarm(session, a, now) for a in queries.claim(session, candidates) if due(a)
        ]
