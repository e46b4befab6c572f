"""Segment status transitions, declared once (with `vigil.states`).

draft --submit--> submitted --accept/reject--> accepted | rejected
pending (proposed by a nurse verdict, a model or a shadow disagreement) --accept/reject-->
draft/pending/rejected --delete--> deleted (kept for its history)
rejected --submit--> submitted ; submitted --withdraw--> draft ; accepted/rejected --reopen--> draft
draft/pending/rejected --edit--> the same state (a rejected segment becomes a draft again)
"""

from __future__ import annotations

from backend.labelling.errors import Conflict
from backend.models.annotations import SegmentStatus
from vigil.states import IllegalTransition, StateMachine

D, P, S, A, R, X = (
    SegmentStatus.DRAFT,
    SegmentStatus.PENDING,
    SegmentStatus.SUBMITTED,
    SegmentStatus.ACCEPTED,
    SegmentStatus.REJECTED,
    SegmentStatus.DELETED,
)


class SegmentTransitionError(IllegalTransition, Conflict):
    """An action the segment's status does not allow (HTTP 409, the message names `action`)."""

    def message(self) -> str:
        return f"action: {super().message()}"


SEGMENT = StateMachine(
    SegmentStatus,
    actions={
        "submit": {D: S, P: S, R: S},
        "withdraw": {S: D},
        "accept": {S: A, P: A},
        "reject": {S: R, P: R},
        "reopen": {A: D, R: D},
        "edit": {D: D, P: P, R: D},
        "delete": {D: X, P: X, R: X},
    },
    initial=D,
    # Segments made by the system: a reviewer's queue gets "pending" proposals (nurse verdicts,
    # shadow disagreements, an exchange file's labels); a dataset's own labels are its ground
    # truth and come in accepted (URFD's importer, and its archive restored).
    entries={"propose": P, "import": A},
    subject="segment",
    error=SegmentTransitionError,
)
#: The actions a client may ask for through the status endpoint.
STATUS_ACTIONS = ("submit", "withdraw", "accept", "reject", "reopen")
REVIEW_ACTIONS = frozenset({"accept", "reject"})
#: Frames and label may change only in these states (a rejected segment becomes a draft again).
EDITABLE = frozenset(SEGMENT.actions["edit"])
#: States a reviewer still has to look at.
IN_REVIEW = frozenset({S, P})


def next_status(current: SegmentStatus | str, action: str) -> SegmentStatus:
    """Where a status action takes a segment (only the actions of the status endpoint)."""
    if action not in STATUS_ACTIONS:
        raise SegmentTransitionError(
            "segment", current, action=action, unknown_action=True, actions=STATUS_ACTIONS
        )
    return SEGMENT.target(current, action)
