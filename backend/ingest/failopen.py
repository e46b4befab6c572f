"""Alarms fail open: what the nurse board gets while storage is stalled.

Like Alertmanager (at least once, fail open), an Emergency a robot decided reaches the nurse
board even when its frames cannot be written yet:

- an Emergency frame not stored within `unstored_alarm_ms` is pushed at once as an alarm
  marked `stored: false` (a negative, provisional id; `key` = robot/transport/kind, the
  identity the stored alarm shares). Once the write goes through, the stored alarm is pushed
  and replaces the provisional card (same `key`, no duplicate);
- a write blocked longer than `storage_stall_seconds` raises a `storage_stalled` technical
  alarm for each robot whose frames wait (also `stored: false`: storage is what is stalled).
  Once the write goes through it is stored, raised and cleared in one go (the audit trail
  keeps the outage and how long it lasted), and that stored, resolved alarm (same key) takes
  the provisional card off the board. Both are logged.

Robots are still acknowledged only after the commit, so no frame is lost: their outboxes
resend what was not acknowledged. Everything here runs on the event loop.
"""

from __future__ import annotations

import itertools
import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from sqlalchemy.orm import Session

from backend.alarms import service as alarms
from backend.alarms.schemas import AlarmOut, alarm_key
from backend.alarms.state import ALARM
from backend.ingest.received import ReceivedFrames
from backend.models._types import utcnow
from backend.models.alarms import PRIORITY_OF_KIND, AlarmKind, AlarmState
from backend.models.robots import Robot
from vigil.classes import Decision
from vigil.protocol import TransportStart

log = logging.getLogger(__name__)

_provisional_ids = itertools.count(1)


def provisional_alarm(
    kind: AlarmKind,
    robot_id: str,
    ward: str | None,
    transport_id: str | None = None,
    patient: str | None = None,
    location: str | None = None,
    details: dict | None = None,
    **fields,
) -> dict:
    """An alarm as pushed to browsers (AlarmOut JSON) that is not (yet) in the database."""
    now = utcnow()
    return AlarmOut(
        id=-next(_provisional_ids),
        kind=kind,
        priority=PRIORITY_OF_KIND[kind],
        state=ALARM.initial,
        robot_id=robot_id,
        ward=ward or "",
        transport_id=transport_id,
        patient=patient,
        location=location,
        raised_at=now,
        updated_at=now,
        acknowledged_at=None,
        resolved_at=None,
        verdict=None,
        reason=None,
        comment=None,
        escalation_level=0,
        realarmed_at=None,
        video_id=None,
        first_seq=fields.get("first_seq"),
        last_seq=fields.get("last_seq"),
        decision_count=fields.get("decision_count", 1),
        model_version=fields.get("model_version"),
        threshold=fields.get("threshold"),
        delay_ms=fields.get("delay_ms"),
        details=details,
        stored=False,
    ).model_dump(mode="json")


@dataclass
class Unstored:
    """Emergency frames of one (robot, transport) not committed yet."""

    alarm: dict
    since: float  # perf_counter of the first frame's arrival
    jobs: set[int] = field(default_factory=set)  # id() of the writer jobs holding them
    pushed: bool = False


class FailOpen:
    def __init__(self, unstored_alarm_s: float, stall_s: float) -> None:
        self.unstored_alarm_s = unstored_alarm_s
        self.stall_s = stall_s
        self.unstored: dict[str, Unstored] = {}
        # Not yet pushed, in arrival order: each tick looks only at those due, not at every
        # unstored Emergency (thousands while a thousand robots' frames wait).
        self._unpushed: deque[tuple[str, Unstored]] = deque()
        self.stalled: dict[str, dict] = {}  # robot id -> its pushed storage_stalled alarm
        self.write_started: float | None = None  # perf_counter when the running commit began
        self._transports: dict[str, tuple[str | None, str | None]] = {}  # id -> patient, location

    # -- robot messages ---------------------------------------------------------------------
    def on_submit(self, job, transport_lookup=None, unalarmed: set[str] | None = None) -> None:
        """`unalarmed`: the transports ('' for none) of the job's Emergency frames without a
        stored alarm the writer knows of (None: all of them); only those are watched."""
        link, message = job.link, job.message
        ward = getattr(link, "ward", None)
        if isinstance(message, TransportStart):
            self._transports[message.transport_id] = (message.patient, message.location)
            return
        if not isinstance(message, ReceivedFrames):
            return
        for frame in message.frames:
            if frame.decision != Decision.EMERGENCY:
                continue
            if unalarmed is not None and (frame.transport_id or "") not in unalarmed:
                continue  # its alarm is stored and on the boards: this frame folds into it
            key = alarm_key(link.robot_id, frame.transport_id, AlarmKind.EMERGENCY)
            entry = self.unstored.get(key)
            if entry is None:
                patient, location = self._transport_info(frame.transport_id, transport_lookup)
                alarm = provisional_alarm(
                    AlarmKind.EMERGENCY,
                    link.robot_id,
                    ward,
                    frame.transport_id,
                    patient,
                    location,
                    first_seq=frame.seq,
                    last_seq=frame.seq,
                    decision_count=0,
                    model_version=frame.model_version,
                    threshold=frame.threshold,
                    delay_ms=frame.delay_ms,
                )
                entry = self.unstored[key] = Unstored(alarm, job.received)
                self._unpushed.append((key, entry))
            alarm = entry.alarm
            alarm["decision_count"] += 1
            alarm["first_seq"] = min(alarm["first_seq"], frame.seq)
            alarm["last_seq"] = max(alarm["last_seq"], frame.seq)
            entry.jobs.add(id(job))

    def any_pushed(self) -> bool:
        """Whether a provisional Emergency is on the boards, waiting for its stored alarm."""
        return any(entry.pushed for entry in self.unstored.values())

    def _transport_info(self, transport_id, lookup) -> tuple[str | None, str | None]:
        if transport_id is None:
            return None, None
        if transport_id in self._transports:
            return self._transports[transport_id]
        known = lookup(transport_id) if lookup is not None else None
        if known is not None:
            return known.patient, known.location
        return None, None

    # -- the writer's commits -----------------------------------------------------------------
    def on_write_start(self, now: float) -> None:
        self.write_started = now

    def on_write_done(self, jobs) -> list[dict]:
        """After a commit (or its failure): forget what it settled; returns the alarms to push
        (storage_stalled cleared)."""
        self.write_started = None
        done = {id(job) for job in jobs}
        for key in list(self.unstored):
            entry = self.unstored[key]
            entry.jobs -= done
            if not entry.jobs:
                del self.unstored[key]
        cleared = []
        if self.stalled:
            log.warning(
                "storage recovered: frame writes go through again (%d robots waited)",
                len(self.stalled),
            )
            at = utcnow().isoformat()
            for alarm in self.stalled.values():
                cleared.append(
                    {
                        **alarm,
                        "state": AlarmState.RESOLVED.value,
                        "resolved_at": at,
                        "updated_at": at,
                    }
                )
            self.stalled = {}
        return cleared

    # -- every tick of the watch ---------------------------------------------------------------
    def stalled_for(self, now: float) -> float | None:
        if self.write_started is None or now - self.write_started < self.stall_s:
            return None
        return now - self.write_started

    def due(self, now: float, waiting: Callable[[], dict[str, str | None]]) -> list[dict]:
        """Alarms to push now: Emergencies waiting too long, storage_stalled for each robot
        (`waiting()`: robot id -> ward, called only while a write is blocked) whose frames wait
        on a blocked write."""
        out = []
        unpushed = self._unpushed
        while unpushed and now - unpushed[0][1].since >= self.unstored_alarm_s:
            key, entry = unpushed.popleft()
            if self.unstored.get(key) is entry and not entry.pushed:
                entry.pushed = True
                alarm = entry.alarm
                log.error(
                    "Emergency of robot %s (transport %s, seq %s) not stored after %.2f s: "
                    "pushed to the nurse board as not yet stored",
                    alarm["robot_id"],
                    alarm["transport_id"],
                    alarm["first_seq"],
                    now - entry.since,
                )
                out.append(dict(alarm))
        blocked = self.stalled_for(now)
        if blocked is not None:
            for robot_id, ward in waiting().items():
                if robot_id in self.stalled:
                    continue
                log.error(
                    "storage stalled: a frame write has been blocked for %.1f s (robot %s waits)",
                    blocked,
                    robot_id,
                )
                alarm = provisional_alarm(
                    AlarmKind.STORAGE_STALLED,
                    robot_id,
                    ward,
                    details={
                        "summary": f"frame writes blocked for over {self.stall_s:g} s: "
                        "alarms are pushed before they are stored",
                        "blocked_since_s": round(blocked, 1),
                    },
                )
                self.stalled[robot_id] = alarm
                out.append(alarm)
        return out

    def record(self, session: Session, cleared: list[dict], blocked_s: float) -> list[dict]:
        """Store the storage_stalled alarms pushed during the stall, raised and cleared (the
        caller commits); returns them as pushed (stored, resolved, same key)."""
        out = []
        note = f"storage recovered: a frame write was blocked {blocked_s:.1f} s"
        for pushed in cleared:
            robot = session.get(Robot, pushed["robot_id"])
            if robot is None:
                continue
            evidence = alarms.DecisionEvidence(seq=robot.last_seq, ts=None)
            with session.no_autoflush:
                alarm, _ = alarms.raise_or_update(
                    session, robot, None, AlarmKind.STORAGE_STALLED, evidence
                )
            alarm.details = {
                **(pushed.get("details") or {}),
                "pushed_at": pushed["raised_at"],
                "blocked_s": round(blocked_s, 1),
            }
            alarms.clear(session, alarm, utcnow(), note)
            session.flush()
            out.append(AlarmOut.model_validate(alarm).model_dump(mode="json"))
        return out

    def provisional(self, alarm_id: int) -> dict | None:
        """The pushed, not yet stored Emergency with this (negative) id, if still unstored."""
        for entry in self.unstored.values():
            if entry.pushed and entry.alarm["id"] == alarm_id:
                return entry.alarm
        return None

    def is_stall_alarm(self, alarm_id: int) -> bool:
        return any(a["id"] == alarm_id for a in self.stalled.values())

    def board(self) -> list[dict]:
        """What a browser connecting now should see beside the stored alarms."""
        return [
            dict(e.alarm)
            for e in self.unstored.values()
            if e.pushed and e.alarm["state"] != AlarmState.RESOLVED.value
        ] + list(self.stalled.values())
