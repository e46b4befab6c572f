"""The alarm state machine, declared once (with `vigil.states`).

    open ──acknowledge──▶ acknowledged ──resolve──▶ resolved
      └──────────────────resolve──────────────────────▲
      └──────────────────clear────────────────────────┘  (technical: the cause ended)

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


OPEN, ACKNOWLEDGED, RESOLVED = AlarmState.OPEN, AlarmState.ACKNOWLEDGED, AlarmState.RESOLVED


class IllegalTransition(_IllegalTransition):
    """An alarm action its state does not allow (HTTP 409)."""


ALARM = StateMachine(
    AlarmState,
    actions={
        AlarmAction.UPDATE: {OPEN: OPEN, ACKNOWLEDGED: ACKNOWLEDGED},
        AlarmAction.ACKNOWLEDGE: {OPEN: ACKNOWLEDGED},
        AlarmAction.RESOLVE: {OPEN: RESOLVED, ACKNOWLEDGED: RESOLVED},
        AlarmAction.ESCALATE: {OPEN: OPEN},
        AlarmAction.REALARM: {ACKNOWLEDGED: ACKNOWLEDGED},
        AlarmAction.CLEAR: {OPEN: RESOLVED, ACKNOWLEDGED: RESOLVED},
    },
    attribute="state",
    initial=OPEN,
    subject="alarm",
    error=IllegalTransition,
)
