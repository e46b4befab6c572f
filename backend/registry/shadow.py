"""Shadow mode bookkeeping: frames where the candidate (shadow) model and the production model
disagree become pending segments in the labelling review queue. Shadow decisions are stored on
the frames by ingest and never raise alarms (ingest alarms on `Frame.decision` only)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.labelling.status import SEGMENT
from backend.models.annotations import AnnotationSegment, SegmentSource
from backend.models.taxonomy import TaxonomyVersion
from backend.models.videos import Frame
from vigil.classes import Decision

# The fine label proposed for the shadow model's decision; the annotator corrects it.
PROPOSED_LABEL = {
    Decision.EMERGENCY: "falling",
    Decision.PAUSE: "too_far_away",
    Decision.NORMAL: "walking",
}
MAX_GAP_FRAMES = 3  # disagreements this close together form one segment


def record_disagreements(session: Session, limit_frames: int = 50_000) -> list[AnnotationSegment]:
    """Add pending review segments for new disagreement runs; returns the new segments."""
    covered = dict(
        session.execute(
            select(AnnotationSegment.video_id, func.max(AnnotationSegment.last_frame))
            .where(AnnotationSegment.source == SegmentSource.SHADOW_DISAGREEMENT)
            .group_by(AnnotationSegment.video_id)
        ).all()
    )
    rows = session.execute(
        select(
            Frame.video_id,
            Frame.index,
            Frame.decision,
            Frame.shadow_decision,
            Frame.model_version,
            Frame.shadow_model_version,
        )
        .where(Frame.shadow_decision.is_not(None), Frame.decision.is_not(None))
        .where(Frame.shadow_decision != Frame.decision)
        .order_by(Frame.video_id, Frame.index)
        .limit(limit_frames)
    ).all()
    taxonomy_version = session.scalar(select(func.max(TaxonomyVersion.version))) or 1
    runs: list[list] = []
    for row in rows:
        if row.index <= covered.get(row.video_id, -1):
            continue
        last = runs[-1] if runs else None
        if (
            last is not None
            and last[0].video_id == row.video_id
            and row.index - last[-1].index <= MAX_GAP_FRAMES
            and row.shadow_decision == last[0].shadow_decision
        ):
            last.append(row)
        else:
            runs.append([row])
    created = []
    for run in runs:
        first, end = run[0], run[-1]
        shadow = Decision(first.shadow_decision)
        segment = AnnotationSegment(
            video_id=first.video_id,
            first_frame=first.index,
            last_frame=end.index,
            label_key=PROPOSED_LABEL[shadow],
            taxonomy_version=taxonomy_version,
            source=SegmentSource.SHADOW_DISAGREEMENT,
            priority=2 if Decision.EMERGENCY in (shadow, Decision(first.decision)) else 1,
            model_version=first.shadow_model_version,
            review_comment=(
                f"shadow {first.shadow_model_version} said {shadow.value}, production "
                f"{first.model_version} said {first.decision} on frames {first.index}-{end.index}"
            ),
        )
        SEGMENT.start(segment, "propose")
        session.add(segment)
        created.append(segment)
    session.flush()
    return created
