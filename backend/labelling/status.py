"""Segment status transitions, written once.

draft --submit--> submitted --accept/reject--> accepted | rejected
pending (proposed by a nurse verdict, a model or a shadow disagreement) --accept/reject-->
draft/pending/rejected --delete--> deleted (kept for its history)
rejected --submit--> submitted ; submitted --withdraw--> draft ; accepted/rejected --reopen--> draft
"""

from __future__ import annotations

from backend.labelling.errors import Conflict
from backend.models.annotations import SegmentStatus

D, P, S, A, R, X = (
    SegmentStatus.DRAFT,
    SegmentStatus.PENDING,
    SegmentStatus.SUBMITTED,
    SegmentStatus.ACCEPTED,
    SegmentStatus.REJECTED,
    SegmentStatus.DELETED,
)

#: action -> (allowed from states, resulting state)
TRANSITIONS: dict[str, tuple[frozenset[SegmentStatus], SegmentStatus]] = {
    "submit": (frozenset({D, P, R}), S),
    "withdraw": (frozenset({S}), D),
    "accept": (frozenset({S, P}), A),
    "reject": (frozenset({S, P}), R),
    "reopen": (frozenset({A, R}), D),
}
REVIEW_ACTIONS = frozenset({"accept", "reject"})
#: Frames and label may change only in these states (a rejected segment becomes a draft again).
EDITABLE = frozenset({D, P, R})
#: States a reviewer still has to look at.
IN_REVIEW = frozenset({S, P})


def next_status(current: SegmentStatus | str, action: str) -> SegmentStatus:
    if action not in TRANSITIONS:
        raise Conflict(f"action: unknown action {action!r} (one of {', '.join(TRANSITIONS)})")
    sources, target = TRANSITIONS[action]
    if SegmentStatus(current) not in sources:
        raise Conflict(f"action: cannot {action} a segment that is {current}")
    return target
