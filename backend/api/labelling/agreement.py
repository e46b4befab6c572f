"""Labelling API: agreement between annotators or with imported labels."""

from __future__ import annotations

from fastapi import APIRouter

from backend.deps import CurrentUser, DbId, SessionDep
from backend.labelling import segments
from backend.labelling.agreement import agreement
from backend.labelling.errors import LabellingError, NotFound
from backend.labelling.queries import (
    agreement_annotators,
    agreement_spans,
)
from backend.labelling.schemas import (
    AgreementOut,
    AnnotatorsOut,
    LabelAgreementOut,
    StageTimingOut,
)
from backend.labelling.taxonomy import load_taxonomy
from vigil.classes import Decision

router = APIRouter(prefix="/api/labelling", tags=["labelling"])


# -- agreement ------------------------------------------------------------------------------


@router.get("/videos/{video_id}/annotators")
def video_annotators(video_id: DbId, session: SessionDep, user: CurrentUser) -> AnnotatorsOut:
    """The video's annotators, and `(imported)` when it holds a dataset's own labels."""
    segments.get_video(session, video_id)
    return AnnotatorsOut(annotators=agreement_annotators(session, video_id))


@router.get("/videos/{video_id}/agreement")
def video_agreement(
    video_id: DbId, a: str, b: str, session: SessionDep, user: CurrentUser
) -> AgreementOut:
    """Agreement of two annotators, or of an annotator with the imported labels (`(imported)`)."""
    video = segments.get_video(session, video_id)
    taxonomy = load_taxonomy(session)
    spans = {}
    for param, who in (("a", a), ("b", b)):
        found = agreement_spans(session, video_id, who)
        if found is None:
            raise NotFound(f"{param}: no user {who!r}")
        if not found:
            raise LabellingError(f"{param}: {who} has no segments on video {video.name}")
        spans[param] = found
    stages = {
        label.key for label in taxonomy.labels if label.decision(video.mode) == Decision.EMERGENCY
    }
    result = agreement(video.frame_count, video.fps, spans["a"], spans["b"], stages)
    return AgreementOut(
        video_id=video.id,
        annotator_a=a,
        annotator_b=b,
        frames_compared=result.frames_compared,
        overall_kappa=result.overall_kappa,
        labels=[LabelAgreementOut(**vars_(x)) for x in result.labels],
        stages=[StageTimingOut(**vars_(x)) for x in result.stages],
    )


def vars_(obj) -> dict:
    return {name: getattr(obj, name) for name in obj.__slots__}
