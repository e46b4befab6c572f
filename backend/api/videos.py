from datetime import datetime

from fastapi import APIRouter, HTTPException, Query, Response, status
from pydantic import BaseModel, ConfigDict
from pydantic_core import to_json

from backend import wards
from backend.deps import MAX_DB_INT, CurrentUser, DbId, SessionDep
from backend.labelling.queries import frames_between, videos_matching
from backend.models.videos import Split, Video
from backend.storage.frame_reads import json_frames
from vigil.classes import Decision, TransportMode

router = APIRouter(prefix="/api/videos", tags=["videos"])

MAX_FRAMES_PER_REQUEST = 2000


class VideoOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    source: str
    generated: bool
    mode: TransportMode
    camera: str | None
    location: str | None
    fps: float
    person: str | None
    split: Split
    transport_id: str | None
    robot_id: str | None
    frame_count: int
    has_rgb: bool = False
    created_at: datetime


class FrameOut(BaseModel):
    index: int
    ts: float
    seq: int | None
    keypoints: list[list[float]]
    depth: list[float | None] | None
    floor: list[float | None] | None
    decision: Decision | None
    scores: dict[str, float] | None
    model_version: str | None
    threshold: float | None
    delay_ms: int | None
    shadow_decision: Decision | None
    shadow_model_version: str | None


def _video_out(video: Video) -> VideoOut:
    out = VideoOut.model_validate(video)
    out.has_rgb = video.rgb_path is not None
    return out


@router.get("")
def list_videos(
    session: SessionDep,
    user: CurrentUser,
    mode: TransportMode | None = None,
    split: Split | None = None,
    source: str | None = None,
) -> list[VideoOut]:
    videos = videos_matching(session, mode, split, source, scope=wards.videos_visible(user))
    return [_video_out(v) for v in videos]


def _video(session: SessionDep, user: CurrentUser, video_id: int) -> Video:
    """The video if the caller's wards include it (backend.wards), else 404."""
    video = wards.visible_video(session, user, video_id)
    if video is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"video {video_id} not found")
    return video


@router.get("/{video_id}")
def get_video(video_id: DbId, session: SessionDep, user: CurrentUser) -> VideoOut:
    return _video_out(_video(session, user, video_id))


@router.get("/{video_id}/frames", response_model=list[FrameOut])
def get_frames(
    video_id: DbId,
    session: SessionDep,
    user: CurrentUser,
    start: int = Query(default=0, ge=0, le=MAX_DB_INT, description="first frame index (inclusive)"),
    end: int | None = Query(
        default=None, ge=0, le=MAX_DB_INT, description="last frame index (inclusive)"
    ),
) -> Response:
    # list[FrameOut], encoded without a pydantic model per frame (backend.storage.frame_reads).
    video = _video(session, user, video_id)
    last = start + MAX_FRAMES_PER_REQUEST - 1 if end is None else end
    if last < start:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_ENTITY, "end must not be before start")
    if last - start + 1 > MAX_FRAMES_PER_REQUEST:
        raise HTTPException(
            status.HTTP_422_UNPROCESSABLE_ENTITY,
            f"at most {MAX_FRAMES_PER_REQUEST} frames per request",
        )
    frames = json_frames(frames_between(session, video, start, last))
    return Response(to_json(frames), media_type="application/json")
