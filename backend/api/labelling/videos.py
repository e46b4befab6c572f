"""Labelling API: the videos with their labelling progress, facets and metadata."""

from __future__ import annotations

from fastapi import APIRouter, Query

from backend.deps import CurrentUser, DbId, SessionDep
from backend.labelling import segments
from backend.labelling.errors import LabellingError
from backend.labelling.queries import (
    facet_values,
    progress_by_video,
    videos_matching,
)
from backend.labelling.schemas import (
    Facets,
    LabellingVideoOut,
    VideoPatch,
)
from backend.labelling.status import IN_REVIEW
from backend.models.videos import Split, Video
from vigil.classes import TransportMode

router = APIRouter(prefix="/api/labelling", tags=["labelling"])


# -- videos ---------------------------------------------------------------------------------


def _video_status(counts: dict[str, int], unreviewed: int) -> str:
    if not any(k for k in counts if k != "labelled_frames"):
        return "unlabelled"
    if counts.get("draft") or counts.get("rejected"):
        return "in_progress"
    if unreviewed:
        return "in_review"
    return "done"


def _video_out(video: Video, progress: dict[str, int]) -> LabellingVideoOut:
    counts = {k: v for k, v in progress.items() if k != "labelled_frames"}
    unreviewed = sum(counts.get(str(s), 0) for s in IN_REVIEW)
    return LabellingVideoOut(
        id=video.id,
        name=video.name,
        source=video.source,
        generated=video.generated,
        mode=video.mode,
        camera=video.camera,
        location=video.location,
        person=video.person,
        split=video.split,
        fps=video.fps,
        frame_count=video.frame_count,
        image_width=video.image_width,
        image_height=video.image_height,
        has_rgb=video.rgb_path is not None,
        has_depth=video.depth_path is not None,
        labelled_frames=progress.get("labelled_frames", 0),
        segment_counts=counts,
        unreviewed=unreviewed,
        status=_video_status(counts, unreviewed),
    )


@router.get("/videos")
def list_videos(
    session: SessionDep,
    user: CurrentUser,
    mode: TransportMode | None = None,
    split: Split | None = None,
    person: str | None = None,
    source: str | None = None,
    unreviewed: bool | None = Query(default=None, description="has segments awaiting review"),
) -> list[LabellingVideoOut]:
    progress = progress_by_video(session)
    out = [
        _video_out(v, progress.get(v.id, {}))
        for v in videos_matching(session, mode, split, source, person)
    ]
    if unreviewed is not None:
        out = [v for v in out if (v.unreviewed > 0) == unreviewed]
    return out


@router.get("/facets")
def facets(session: SessionDep, user: CurrentUser) -> Facets:
    def values(column) -> list[str]:
        return facet_values(session, column)

    return Facets(
        persons=values(Video.person),
        locations=values(Video.location),
        cameras=values(Video.camera),
        sources=values(Video.source),
    )


@router.get("/videos/{video_id}")
def get_video(video_id: DbId, session: SessionDep, user: CurrentUser) -> LabellingVideoOut:
    video = segments.get_video(session, video_id)
    return _video_out(video, progress_by_video(session).get(video.id, {}))


@router.patch("/videos/{video_id}")
def patch_video(
    video_id: DbId, body: VideoPatch, session: SessionDep, user: CurrentUser
) -> LabellingVideoOut:
    video = segments.get_video(session, video_id)
    for field, value in body.model_dump(exclude_unset=True).items():
        if field == "split" and value is None:
            raise LabellingError("split: must be train, test or unassigned")
        setattr(video, field, value)
    session.flush()
    return _video_out(video, progress_by_video(session).get(video.id, {}))
