"""Acting during a storage stall: a nurse acknowledges or resolves an alarm not yet stored.

A provisional alarm (`backend.ingest.failopen`: an Emergency pushed to the board before its
frames could be committed, negative id) can be acknowledged and resolved like a stored one. The
action cannot wait for the database (that is what is stalled), so it is

- written at once to a journal file (JSON lines, fsynced; `stall_actions_path`), which outlives a
  restart: the robot's outbox resends the unacknowledged frames, the alarm is stored then, and
  the journal's action applied to it;
- shown on the board at once (the provisional card is pushed again, acknowledged or resolved);
- applied by the frame writer in the same transaction that stores the alarm (so the stored
  alarm reaches the board already acknowledged), or, when the alarm was stored before the
  action, in the writer's next commit. The audit says so: "acknowledged by nurse:nina at T
  while storage was stalled; applied at T2".

The stored alarm an action belongs to is the unresolved one with the provisional alarm's key
(robot/transport/kind) whose sequence numbers overlap the provisional one's, so a later
Emergency on the same transport is never acknowledged by an old action.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import uuid
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import datetime
from pathlib import Path

from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session

from backend.alarms import service as alarms
from backend.alarms.state import ALARM, AlarmAction
from backend.ingest.failopen import FailOpen
from backend.models._types import utcnow
from backend.models.alarms import AlarmKind, AlarmState, FalseAlarmReason, Verdict
from backend.models.robots import Robot
from backend.models.users import User
from backend.settings import REPO_ROOT
from backend.wards import sees_ward

log = logging.getLogger(__name__)


def journal_path(database_url: str, configured: Path | None) -> Path:
    """`stall_actions_path`, else beside the SQLite file, else var/ named after the database."""
    if configured is not None:
        return configured
    url = make_url(database_url)
    if url.get_backend_name() == "sqlite" and url.database:
        return Path(f"{url.database}.stall-actions.jsonl")
    return REPO_ROOT / "var" / f"stall-actions-{url.database or 'vigil'}.jsonl"


@dataclass
class StallAction:
    """One acknowledgement or resolution of a provisional alarm, as journalled."""

    id: str
    action: str  # "acknowledge" or "resolve"
    provisional_id: int
    robot_id: str
    transport_id: str | None
    kind: str
    first_seq: int | None
    last_seq: int | None
    user_id: int
    actor: str  # role:username
    at: str  # ISO time the nurse acted
    comment: str | None = None
    verdict: str | None = None
    reason: str | None = None

    def note(self, applied_at: datetime) -> str:
        what = "acknowledged" if self.action == AlarmAction.ACKNOWLEDGE else "resolved"
        return (
            f"{what} by {self.actor} at {self.at} while storage was stalled "
            f"(provisional alarm {self.provisional_id}); applied at {applied_at.isoformat()}"
        )


class StallActions:
    """The journal and the actions in it not applied yet (thread safe: the API adds from its
    threads, the frame writer applies in its own)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lock = threading.Lock()
        self._pending: dict[str, StallAction] = {}
        self._load()

    def _load(self) -> None:
        if not self.path.exists():
            return
        for line in self.path.read_text().splitlines():
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
                if "applied" in entry:
                    self._pending.pop(entry["applied"], None)
                else:
                    action = StallAction(**entry)
                    self._pending[action.id] = action
            except (ValueError, TypeError):
                log.exception("stall action journal %s: unreadable line skipped", self.path)
        if self._pending:
            log.warning(
                "%d actions on alarms not yet stored found in %s: applied once stored",
                len(self._pending),
                self.path,
            )

    def _append(self, entries: list[dict]) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a") as journal:
            for entry in entries:
                journal.write(json.dumps(entry) + "\n")
            journal.flush()
            os.fsync(journal.fileno())

    def add(self, action: StallAction) -> None:
        """Journal an action (durable when this returns)."""
        with self._lock:
            self._append([asdict(action)])
            self._pending[action.id] = action

    def pending(self) -> list[StallAction]:
        with self._lock:
            return list(self._pending.values())

    def done(self, ids: list[str]) -> None:
        """Forget applied (or dropped) actions; the journal is emptied once none is left."""
        if not ids:
            return
        with self._lock:
            for action_id in ids:
                self._pending.pop(action_id, None)
            if self._pending:
                self._append([{"applied": action_id} for action_id in ids])
            else:
                self.path.unlink(missing_ok=True)

    # -- in the frame writer's transaction --------------------------------------------------
    def apply(self, session: Session) -> list[str]:
        """Apply what can be applied to the stored alarms (the caller commits, then calls
        `done` with the ids returned: applied, or dropped as no longer applicable)."""
        settled = []
        for action in self.pending():
            if _apply_one(session, action):
                settled.append(action.id)
        return settled


def _apply_one(session: Session, action: StallAction) -> bool:
    """True: applied or dropped (never applicable); False: its alarm is not stored yet."""
    alarm = alarms.find_unresolved(
        session, action.robot_id, action.transport_id, AlarmKind(action.kind)
    )
    if alarm is not None and not _same_alarm(alarm, action):
        alarm = None
    if alarm is None:
        robot = session.get(Robot, action.robot_id)
        stored = (
            robot is not None
            and robot.last_seq is not None
            and action.last_seq is not None
            and robot.last_seq >= action.last_seq
        )
        if stored:  # its frames are stored and no unresolved alarm has them: resolved since
            log.warning(
                "%s of provisional alarm %s by %s dropped: the stored alarm is already resolved",
                action.action,
                action.provisional_id,
                action.actor,
            )
        return stored
    user = session.get(User, action.user_id)
    if user is None or AlarmState(alarm.state) not in ALARM.actions[action.action]:
        log.warning(
            "%s of provisional alarm %s by %s dropped: alarm %s is %s",
            action.action,
            action.provisional_id,
            action.actor,
            alarm.id,
            alarm.state,
        )
        return True
    now = utcnow()
    note = action.note(now)
    if action.action == AlarmAction.ACKNOWLEDGE:
        alarms.acknowledge(session, alarm, user, action.comment, audit_prefix=note)
    else:
        verdict = Verdict(action.verdict)
        reason = FalseAlarmReason(action.reason) if action.reason else None
        alarms.resolve(session, alarm, user, verdict, reason, action.comment, audit_prefix=note)
    log.warning("alarm %s: %s", alarm.id, note)
    return True


def _same_alarm(alarm, action: StallAction) -> bool:
    """The stored alarm holds the provisional one's frames (their sequence numbers overlap)."""
    if action.first_seq is None or alarm.first_seq is None:
        return True
    return alarm.first_seq <= action.last_seq and (alarm.last_seq or alarm.first_seq) >= (
        action.first_seq
    )


def new_action(
    action: AlarmAction,
    provisional: dict,
    user: User,
    comment: str | None = None,
    verdict: Verdict | None = None,
    reason: FalseAlarmReason | None = None,
) -> StallAction:
    return StallAction(
        id=uuid.uuid4().hex,
        action=action.value,
        provisional_id=provisional["id"],
        robot_id=provisional["robot_id"],
        transport_id=provisional["transport_id"],
        kind=provisional["kind"],
        first_seq=provisional["first_seq"],
        last_seq=provisional["last_seq"],
        user_id=user.id,
        actor=f"{user.role}:{user.username}",
        at=utcnow().isoformat(),
        comment=comment,
        verdict=verdict.value if verdict else None,
        reason=reason.value if reason else None,
    )


class NotActionable(Exception):
    """A provisional id this backend cannot act on (HTTP 404 or 409 with the message)."""

    def __init__(self, status_code: int, message: str) -> None:
        super().__init__(message)
        self.status_code = status_code
        self.message = message


def act_on_provisional(
    fail_open: FailOpen,
    journal: StallActions,
    user: User,
    alarm_id: int,
    action: AlarmAction,
    comment: str | None = None,
    verdict: Verdict | None = None,
    reason: FalseAlarmReason | None = None,
) -> tuple[dict, Callable[[], None]]:
    """Journal a nurse's action on a provisional alarm; returns the card as it now shows and
    what updates the board's copy (to run on the event loop, then push the card)."""
    if fail_open.is_stall_alarm(alarm_id):
        raise NotActionable(
            409, "a storage-stalled alarm clears itself once storage recovers: nothing to do"
        )
    provisional = fail_open.provisional(alarm_id)
    if provisional is None or not sees_ward(user, provisional["ward"]):
        raise NotActionable(
            404, f"alarm {alarm_id} not found (if it has just been stored, act on the stored one)"
        )
    new_state = ALARM.target(provisional["state"], action, obj=provisional["id"])
    entry = new_action(action, provisional, user, comment, verdict, reason)
    journal.add(entry)
    by = f"{user.username}"
    change: dict = {"state": new_state.value, "updated_at": entry.at}
    if action == AlarmAction.ACKNOWLEDGE:
        change |= {"acknowledged_at": entry.at, "acknowledged_by": by, "comment": comment}
    else:
        change |= {
            "resolved_at": entry.at,
            "resolved_by": by,
            "verdict": entry.verdict,
            "reason": entry.reason,
            "comment": comment,
        }  # noqa: E501
    log.warning(
        "provisional alarm %s (%s): %s by %s while storage is stalled; journalled, "
        "applied once stored",
        alarm_id,
        provisional["key"],
        action,
        entry.actor,
    )  # noqa
    return {**provisional, **change}, lambda: provisional.update(change)
