"""The alarm state machine, declared once (with `vigil.states`).

    open ──acknowledge──▶ acknowledged ──resolve──▶ resolved
      └──────────────────resolve──────────────────────▲
      └──────────────────clear────────────────────────┘  (technical: the cause ended)
      └──miss──▶ missed ──acknowledge──▶ acknowledged      (Emergency past the last
                   └──────resolve──────▶ resolved          escalation level)

"missed: needs review" is latched: new decisions, the transport's end or the robot going
offline leave it missed; only a person (acknowledge or resolve) moves it on.

Escalation and re-alarm do not change the state: they raise `escalation_level` or
`realarmed_at` on an open or acknowledged alarm and push it again.
"""

from enum import StrEnum

from backend.models.alarms import AlarmState
from vigil.states import IllegalTransition as _IllegalTransition
from vigil.states import StateMachine


class AlarmAction(StrEnum):
    RAISE = "raise"
    UPDATE = "update"
    ACKNOWLEDGE = "acknowledge"
    RESOLVE = "resolve"
    ESCALATE = "escalate"
    REALARM = "realarm"
    CLEAR = "clear"  # the system resolves a technical alarm whose cause ended (no verdict)
    MISS = "miss"  # the escalation chain ended without an acknowledgement
    # The robot reports its emergency stop was reset on the robot (not by a resolve): audited,
    # the alarm's state does not change.
    ROBOT_RESET = "robot_reset"
    # The robot reports what it does (stopped, paused, driving again): audited, and shown on
    # the alarm; the alarm's state does not change.
    ROBOT_BEHAVIOUR = "robot_behaviour"
    # The alarm distribution reports a disposition on a clinician's device (delivered, read,
    # accepted, rejected): audited and shown; the state does not change.
    DISPOSITION = "disposition"


OPEN, ACKNOWLEDGED, RESOLVED = AlarmState.OPEN, AlarmState.ACKNOWLEDGED, AlarmState.RESOLVED
MISSED = AlarmState.MISSED


class IllegalTransition(_IllegalTransition):
    """An alarm action its state does not allow (HTTP 409)."""


ALARM = StateMachine(
    AlarmState,
    actions={
        AlarmAction.UPDATE: {OPEN: OPEN, ACKNOWLEDGED: ACKNOWLEDGED, MISSED: MISSED},
        AlarmAction.ACKNOWLEDGE: {OPEN: ACKNOWLEDGED, MISSED: ACKNOWLEDGED},
        AlarmAction.RESOLVE: {OPEN: RESOLVED, ACKNOWLEDGED: RESOLVED, MISSED: RESOLVED},
        # A missed Emergency escalates on to the ward's further responders (still missed).
        AlarmAction.ESCALATE: {OPEN: OPEN, MISSED: MISSED},
        AlarmAction.REALARM: {ACKNOWLEDGED: ACKNOWLEDGED},
        AlarmAction.CLEAR: {OPEN: RESOLVED, ACKNOWLEDGED: RESOLVED},
        AlarmAction.MISS: {OPEN: MISSED},
        AlarmAction.ROBOT_RESET: {s: s for s in AlarmState},
        AlarmAction.ROBOT_BEHAVIOUR: {s: s for s in AlarmState},
        AlarmAction.DISPOSITION: {s: s for s in AlarmState},
    },
    attribute="state",
    initial=OPEN,
    subject="alarm",
    error=IllegalTransition,
)
