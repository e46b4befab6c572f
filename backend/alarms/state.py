"""The alarm state machine, written down once.

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


class AlarmAction(StrEnum):
    RAISE = "raise"
    UPDATE = "update"
    ACKNOWLEDGE = "acknowledge"
    RESOLVE = "resolve"
    ESCALATE = "escalate"
    REALARM = "realarm"
    CLEAR = "clear"  # the system resolves a technical alarm whose cause ended (no verdict)
    MISS = "miss"  # the escalation chain ended without an acknowledgement


TRANSITIONS: dict[tuple[AlarmState, AlarmAction], AlarmState] = {
    (AlarmState.OPEN, AlarmAction.UPDATE): AlarmState.OPEN,
    (AlarmState.ACKNOWLEDGED, AlarmAction.UPDATE): AlarmState.ACKNOWLEDGED,
    (AlarmState.OPEN, AlarmAction.ACKNOWLEDGE): AlarmState.ACKNOWLEDGED,
    (AlarmState.OPEN, AlarmAction.RESOLVE): AlarmState.RESOLVED,
    (AlarmState.ACKNOWLEDGED, AlarmAction.RESOLVE): AlarmState.RESOLVED,
    (AlarmState.OPEN, AlarmAction.ESCALATE): AlarmState.OPEN,
    (AlarmState.ACKNOWLEDGED, AlarmAction.REALARM): AlarmState.ACKNOWLEDGED,
    (AlarmState.OPEN, AlarmAction.CLEAR): AlarmState.RESOLVED,
    (AlarmState.ACKNOWLEDGED, AlarmAction.CLEAR): AlarmState.RESOLVED,
    (AlarmState.OPEN, AlarmAction.MISS): AlarmState.MISSED,
    (AlarmState.MISSED, AlarmAction.UPDATE): AlarmState.MISSED,
    (AlarmState.MISSED, AlarmAction.ACKNOWLEDGE): AlarmState.ACKNOWLEDGED,
    (AlarmState.MISSED, AlarmAction.RESOLVE): AlarmState.RESOLVED,
}


class IllegalTransition(Exception):
    def __init__(self, state: AlarmState, action: AlarmAction) -> None:
        super().__init__(f"cannot {action.value} an alarm that is {state.value}")
        self.state = state
        self.action = action


def next_state(state: AlarmState | str, action: AlarmAction) -> AlarmState:
    state = AlarmState(state)
    try:
        return TRANSITIONS[(state, action)]
    except KeyError:
        raise IllegalTransition(state, action) from None
