"""The outbox message's state machine, declared once (with `vigil.states`).

pending ──acknowledge (AA)──▶ delivered
   └─────refuse (AE)────────▶ refused      (AR, no answer, no connection: stays pending
                                            and is sent again with the same MSH-10)
"""

from enum import StrEnum

from backend.models.alarms import MessageStatus
from vigil.states import StateMachine


class MessageAction(StrEnum):
    ACKNOWLEDGE = "acknowledge"
    REFUSE = "refuse"


PENDING, DELIVERED, REFUSED = MessageStatus.PENDING, MessageStatus.DELIVERED, MessageStatus.REFUSED

MESSAGE = StateMachine(
    MessageStatus,
    actions={
        MessageAction.ACKNOWLEDGE: {PENDING: DELIVERED},
        MessageAction.REFUSE: {PENDING: REFUSED},
    },
    attribute="status",
    initial=PENDING,
    subject="alarm message",
)
