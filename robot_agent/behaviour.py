"""What the robot does with its decisions: the on-robot behaviour state machine.

Driven by every frame's decision after the delay filter (`Pipeline.process`), on the agent's
event loop, with no network in the way:

- `transporting` -> `paused` on Pause (wheelchair and combined modes), -> `emergency_stop` on
  Emergency (every mode);
- `paused` -> `transporting` only after the decision has been Normal for `hold_s` (source time);
- `emergency_stop` never resumes by itself: only `release` (the backend's `alarm_resolved`) or
  `reset` (a local reset: `vigil-robot reset`, or `reset` on the local socket) leaves it;
- `detection_degraded`: no model decides, the patient has not been seen for `unseen_s`, detection
  degraded (an input missing) or the model's file was refused. What the robot does then is the
  `degraded_action` setting (slow or stop), told in the reason; it never carries on silently.

Every change goes to the listeners (the local socket, the hook) at once, as a `BehaviourChange`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from enum import StrEnum

from vigil.classes import BehaviourState, Decision, TransportMode
from vigil.states import StateMachine

log = logging.getLogger(__name__)


class DegradedAction(StrEnum):
    SLOW = "slow"
    STOP = "stop"


_T, _P, _E, _D = (
    BehaviourState.TRANSPORTING,
    BehaviourState.PAUSED,
    BehaviourState.EMERGENCY_STOP,
    BehaviourState.DETECTION_DEGRADED,
)

BEHAVIOUR = StateMachine(
    BehaviourState,
    actions={
        "pause": {_T: _P},
        "resume": {_P: _T},
        "emergency": {_T: _E, _P: _E, _D: _E},
        "degrade": {_T: _D, _P: _D},
        "recover": {_D: _T},
        # Only a nurse's resolve (backend) or a local reset leave an emergency stop.
        "release": {_E: _T},
        "reset": {_E: _T},
    },
    attribute="state",
    initial=_T,
    subject="robot behaviour",
)

#: Modes in which a Pause decision pauses the transport.
PAUSING_MODES = frozenset({TransportMode.WHEELCHAIR, TransportMode.COMBINED})


@dataclass(frozen=True, slots=True)
class BehaviourChange:
    """One line of the local command contract (docs/robot_agent.md)."""

    state: str
    reason: str
    since: float  # Unix time the state was entered
    transport_id: str | None
    alarm_id: int | None
    event: str = "behaviour"  # or "alarm_acknowledged": help is coming, state unchanged
    acknowledged_by: str | None = None

    def as_dict(self) -> dict:
        out = asdict(self)
        if out["acknowledged_by"] is None:
            del out["acknowledged_by"]
        return out


Listener = Callable[[BehaviourChange], None]


class Behaviour:
    def __init__(
        self,
        mode: TransportMode,
        hold_s: float = 2.0,
        degraded_action: DegradedAction | str = DegradedAction.STOP,
        unseen_s: float = 3.0,
        robot_id: str = "",
    ) -> None:
        self.mode = TransportMode(mode)
        self.hold_s = hold_s
        self.degraded_action = DegradedAction(degraded_action)
        self.unseen_s = unseen_s
        self.robot_id = robot_id
        BEHAVIOUR.start(self)
        self.since = time.time()
        self.reason = "started"
        self.transport_id: str | None = None
        self.alarm_id: int | None = None
        self.listeners: list[Listener] = []
        self._normal_since: float | None = None
        self._unseen_since: float | None = None
        #: local resets made: (ts, transport_id, alarm_id, who)
        self.resets: list[tuple[float, str | None, int | None, str]] = []
        #: called on each local reset with (ts, transport_id, alarm_id, who): the agent queues
        #: an emergency_reset message for the backend (sent when it is reachable)
        self.on_reset: Callable[[float, str | None, int | None, str], None] | None = None

    # --- the decision path ---------------------------------------------------------------
    def update(
        self,
        decision: Decision | None,
        ts: float,
        *,
        seen: bool = True,
        degraded: str | None = None,
        transport_id: str | None = None,
    ) -> BehaviourChange | None:
        """One frame: `decision` after the delay filter (None: no model decides), `ts` its
        time, `degraded` why detection is degraded (None: it is not)."""
        if transport_id != self.transport_id:
            self.transport_id = transport_id
            self._unseen_since = None
        state = self.state
        if state == _E:
            return None  # never resumes by itself
        if decision == Decision.EMERGENCY:
            self._normal_since = None
            return self._act("emergency", ts, "Emergency decision: stop, call for help")
        if seen:
            self._unseen_since = None
        elif self._unseen_since is None:
            self._unseen_since = ts
        why = degraded
        if why is None and decision is None:
            why = "no usable model decides"
        if (
            why is None
            and self._unseen_since is not None
            and ts - self._unseen_since >= (self.unseen_s - 1e-6)
        ):
            why = f"patient not seen for {ts - self._unseen_since:.1f} s"
        if why is not None:
            if state != _D:
                return self._act("degrade", ts, f"{why}; robot must {self.degraded_action.value}")
            return None
        if state == _D:
            return self._act("recover", ts, "detection usable again")
        pausing = decision == Decision.PAUSE and self.mode in PAUSING_MODES
        if pausing:
            self._normal_since = None
            if state == _T:
                return self._act("pause", ts, "Pause decision")
            return None
        if state == _P:
            if self._normal_since is None:
                self._normal_since = ts
            if ts - self._normal_since >= self.hold_s - 1e-6:
                self._normal_since = None
                return self._act("resume", ts, f"Normal for {self.hold_s:g} s")
        return None

    # --- from outside the frame path -----------------------------------------------------
    def resolved(self, alarm_id: int | None, by: str | None, ts: float | None = None):
        """The backend says a nurse resolved the alarm: an emergency stop is released."""
        if self.state != _E:
            return None
        who = f" by {by}" if by else ""
        if alarm_id is not None:
            self.alarm_id = alarm_id
        return self._act("release", ts, f"alarm {alarm_id} resolved{who} on the board")

    def reset(self, ts: float | None = None, who: str = "local") -> BehaviourChange | None:
        """A local reset on the robot (CLI or the local socket); reported to the backend."""
        if self.state != _E:
            return None
        ts = time.time() if ts is None else ts
        record = (ts, self.transport_id, self.alarm_id, who)
        self.resets.append(record)
        if self.on_reset is not None:
            self.on_reset(*record)
        return self._act("reset", ts, f"emergency stop reset on the robot ({who})")

    def acknowledged(self, alarm_id: int, by: str, at: float) -> BehaviourChange:
        """The backend says a nurse acknowledged the alarm: help is coming (state unchanged)."""
        self.alarm_id = alarm_id
        change = BehaviourChange(
            self.state.value,
            f"alarm {alarm_id} acknowledged by {by}: help is coming",
            at,
            self.transport_id,
            alarm_id,
            event="alarm_acknowledged",
            acknowledged_by=by,
        )
        log.warning("robot %s: %s", self.robot_id, change.reason)
        self._tell(change)
        return change

    def current(self) -> BehaviourChange:
        return BehaviourChange(
            self.state.value, self.reason, self.since, self.transport_id, self.alarm_id
        )

    def _act(self, action: str, ts: float | None, reason: str) -> BehaviourChange:
        BEHAVIOUR.act(self, action)
        self.since = time.time() if ts is None else ts
        self.reason = reason
        # A release or reset names the alarm it ends (the backend writes it on that alarm, not
        # on one the transport raised since); the robot is then on no alarm.
        released = self.alarm_id if action in ("release", "reset") else None
        if action in ("release", "reset"):
            self.alarm_id = None
        change = self.current()
        if released is not None:
            change = replace(change, alarm_id=released)
        (log.error if self.state == _E else log.warning)(
            "robot %s behaviour: %s (%s)", self.robot_id, self.state.value.upper(), reason
        )
        self._tell(change)
        return change

    def _tell(self, change: BehaviourChange) -> None:
        for listener in self.listeners:
            try:
                listener(change)
            except Exception:  # a broken listener must not stop the frame path
                log.exception("behaviour listener failed")
