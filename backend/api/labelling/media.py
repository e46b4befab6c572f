"""Labelling API: RGB frames (head blurred), the model lane and the 3D view."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response
from fastapi import Path as FastPath

from backend import wards
from backend.deps import MAX_DB_INT, CurrentUser, DbId, SessionDep
from backend.labelling import segments
from backend.labelling.errors import Forbidden, LabellingError, NotFound
from backend.labelling.probability import SUGGESTED_LABEL
from backend.labelling.queries import (
    frame_keypoints,
    video_frames,
)
from backend.labelling.rgb import blur_head, crop, encode_jpeg
from backend.labelling.schemas import (
    ProbabilityOut,
    SuggestionOut,
    View3DOut,
)
from backend.models.users import Role
from backend.services import ServicesDep
from vigil.skeleton import decode_keypoints

router = APIRouter(prefix="/api/labelling", tags=["labelling"])


# -- pictures and model lane ----------------------------------------------------------------


@router.get(
    "/videos/{video_id}/rgb/{frame}",
    response_class=Response,
    responses={200: {"content": {"image/jpeg": {}}}},
)
def rgb_frame(
    video_id: DbId,
    frame: Annotated[int, FastPath(ge=0, le=MAX_DB_INT)],
    services: ServicesDep,
    session: SessionDep,
    user: CurrentUser,
    blur: bool = Query(default=True, description="blur the head; only annotators may turn off"),
) -> Response:
    video = wards.visible_video(session, user, video_id)  # nurses: their ward's robots only
    if video is None:
        raise NotFound(f"video {video_id} not found")
    if video.rgb_path is None:
        raise NotFound(f"video {video.name} has no RGB clip")
    if not 0 <= frame < video.frame_count:
        raise LabellingError(f"frame: {frame} is outside 0..{video.frame_count - 1}")
    if not blur and user.role != Role.ANNOTATOR:
        raise Forbidden("blur: only annotators may see unblurred faces")
    headers = {"Cache-Control": "private, max-age=3600"}
    cached = services.labelling.rgb_jpegs.get((video.id, frame, blur))
    if cached is not None:
        return Response(cached, media_type="image/jpeg", headers=headers)
    number = max(frame + video.rgb_frame_offset, 0)
    picture = crop(services.labelling.rgb_frames.get(video.rgb_path, number), video.rgb_crop)
    if blur:
        blob = frame_keypoints(session, video, frame)
        keypoints = decode_keypoints(blob) if blob is not None else None
        height, width = picture.shape[:2]
        scale = (
            width / video.image_width if video.image_width else float(width),
            height / video.image_height if video.image_height else float(height),
        )
        picture = blur_head(picture, keypoints, scale)
    data = encode_jpeg(picture)
    services.labelling.rgb_jpegs.put((video.id, frame, blur), data)
    return Response(data, media_type="image/jpeg", headers=headers)


@router.get("/videos/{video_id}/probability")
def probability_lane(
    video_id: DbId, services: ServicesDep, session: SessionDep, user: CurrentUser
) -> ProbabilityOut:
    video = segments.get_video(session, video_id)
    lane = services.labelling.model_lane.lane(session, video)
    return ProbabilityOut(
        video_id=video.id,
        source=lane.source,
        model_version=lane.model_version,
        threshold=lane.threshold,
        probability=lane.probability,
        suggestions=[
            SuggestionOut(first_frame=f, last_frame=t, label_key=SUGGESTED_LABEL)
            for f, t in lane.suggestions
        ],
        error=lane.error,
    )


@router.post("/videos/{video_id}/view3d")
def view_3d(
    video_id: DbId,
    services: ServicesDep,
    session: SessionDep,
    user: CurrentUser,
    frame: int = Query(
        ge=0, le=MAX_DB_INT, description="frame to show; the nearest frames with depth are used"
    ),
) -> View3DOut:
    """Show the frame (and up to 30 nearby frames with depth) in 3D in the viser viewer."""
    video = segments.get_video(session, video_id)
    if frame >= video.frame_count:
        raise LabellingError(f"frame: {frame} is outside 0..{video.frame_count - 1}")
    indices, keypoints, depth, _ = video_frames(session, video)
    result = services.labelling.viewer3d.show(
        video.name, indices, keypoints, depth, video.intrinsics, frame
    )
    return View3DOut(
        url=result.url, frames_shown=result.frames_shown, centre_frame=result.centre_frame
    )
