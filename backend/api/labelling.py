"""Labelling workspace API: videos with progress, segments, review, export/import, agreement,
RGB frames and the model lane. Thin: the work is in backend.labelling."""

from __future__ import annotations

import json
from typing import Annotated, Literal
from urllib.parse import quote

from fastapi import APIRouter, FastAPI, Query, Request, Response, UploadFile, status
from fastapi import Path as FastPath
from fastapi.responses import JSONResponse

from backend import wards
from backend.alarm_review.feedback import placeholder_name
from backend.deps import MAX_DB_INT, CurrentUser, DbId, SessionDep
from backend.labelling import exchange, export, segments
from backend.labelling.agreement import agreement
from backend.labelling.errors import Forbidden, LabellingError, NotFound
from backend.labelling.probability import SUGGESTED_LABEL
from backend.labelling.queries import (
    agreement_annotators,
    agreement_spans,
    facet_values,
    frame_keypoints,
    progress_by_video,
    user_by_name,
    usernames,
    video_frames,
    video_modes,
    video_segments,
    videos_matching,
)
from backend.labelling.review import review_queue
from backend.labelling.rgb import blur_head, crop, encode_jpeg
from backend.labelling.schemas import (
    AgreementOut,
    AnnotatorsOut,
    Facets,
    ImportOut,
    LabelAgreementOut,
    LabellingVideoOut,
    ProbabilityOut,
    QueueItemOut,
    ReviewIn,
    SegmentEventOut,
    SegmentIn,
    SegmentOut,
    SegmentPatch,
    StageTimingOut,
    StatusAction,
    SubmitAllOut,
    SuggestionOut,
    VideoPatch,
    View3DOut,
)
from backend.labelling.status import IN_REVIEW
from backend.labelling.taxonomy import load_taxonomy
from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.users import Role
from backend.models.videos import Split, Video
from backend.services import ServicesDep
from vigil.classes import Decision, TransportMode
from vigil.skeleton import decode_keypoints

router = APIRouter(prefix="/api/labelling", tags=["labelling"])

ExportFormat = Literal["csv", "json", "coco"]
#: Each format its own file name: a JSON and a COCO export of one video never overwrite each other.
EXPORT_SUFFIX: dict[str, str] = {"csv": "csv", "json": "json", "coco": "coco.json"}


def install(app: FastAPI) -> None:
    """Start-up wiring: the routes, and 4xx for labelling errors (the frame cache, model lane
    and 3D viewer are services: backend.services.Labelling)."""

    @app.exception_handler(LabellingError)
    def labelling_error(request: Request, error: LabellingError) -> JSONResponse:
        return JSONResponse({"detail": str(error)}, status_code=error.status_code)

    app.include_router(router)


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


# -- segments -------------------------------------------------------------------------------


def _segment_outs(session, items: list[AnnotationSegment]) -> list[SegmentOut]:
    taxonomy = load_taxonomy(session)
    names = usernames(session, [s.annotator_id for s in items] + [s.reviewer_id for s in items])
    modes = video_modes(session, {s.video_id for s in items})
    out = []
    for s in items:
        label = taxonomy.labels.get(s.label_key)
        item = SegmentOut.model_validate(s)
        item.label_name = label.name if label else placeholder_name(s.label_key)
        item.decision = label.decision(modes[s.video_id]) if label else None
        item.annotator = names.get(s.annotator_id)
        item.reviewer = names.get(s.reviewer_id)
        out.append(item)
    return out


@router.get("/videos/{video_id}/segments")
def list_segments(
    video_id: DbId,
    session: SessionDep,
    user: CurrentUser,
    annotator: str | None = None,
    status_: list[SegmentStatus] | None = Query(default=None, alias="status"),
) -> list[SegmentOut]:
    segments.get_video(session, video_id)
    items = video_segments(
        session, video_id, status_ or [s for s in SegmentStatus if s != SegmentStatus.DELETED]
    )
    if annotator is not None:
        owner = user_by_name(session, annotator)
        items = [s for s in items if owner is not None and s.annotator_id == owner.id]
    return _segment_outs(session, items)


@router.post("/videos/{video_id}/segments", status_code=status.HTTP_201_CREATED)
def create_segment(
    video_id: DbId, body: SegmentIn, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    video = segments.get_video(session, video_id)
    segment = segments.create_segment(
        session,
        video,
        segments.SegmentDraft(body.first_frame, body.last_frame, body.label_key),
        user,
        source=SegmentSource(body.source),
    )
    return _segment_outs(session, [segment])[0]


@router.patch("/segments/{segment_id}")
def update_segment(
    segment_id: DbId, body: SegmentPatch, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.update_segment(session, segment, user, **body.model_dump(exclude_unset=True))
    return _segment_outs(session, [segment])[0]


@router.delete("/segments/{segment_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_segment(segment_id: DbId, session: SessionDep, user: CurrentUser) -> Response:
    segments.delete_segment(session, segments.get_segment(session, segment_id), user)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/segments/{segment_id}/status")
def change_status(
    segment_id: DbId, body: StatusAction, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.transition(session, segment, user, body.action, body.comment)
    return _segment_outs(session, [segment])[0]


@router.post("/videos/{video_id}/submit")
def submit_drafts(video_id: DbId, session: SessionDep, user: CurrentUser) -> SubmitAllOut:
    """Submit every draft (and rejected, revised) segment of the caller on this video."""
    segments.get_video(session, video_id)
    mine = [
        s
        for s in video_segments(session, video_id, [SegmentStatus.DRAFT, SegmentStatus.REJECTED])
        if s.annotator_id == user.id
    ]
    if not mine:
        raise LabellingError("segments: you have no draft segments on this video to submit")
    for segment in mine:
        segments.transition(session, segment, user, "submit", None)
    return SubmitAllOut(submitted=[s.id for s in mine])


@router.post("/segments/{segment_id}/review")
def review_segment(
    segment_id: DbId, body: ReviewIn, session: SessionDep, user: CurrentUser
) -> SegmentOut:
    segment = segments.get_segment(session, segment_id)
    segments.transition(session, segment, user, body.decision, body.comment)
    return _segment_outs(session, [segment])[0]


@router.get("/segments/{segment_id}/history")
def segment_history(
    segment_id: DbId, session: SessionDep, user: CurrentUser
) -> list[SegmentEventOut]:
    segments.get_segment(session, segment_id)
    events = segments.history(session, segment_id)
    names = usernames(session, [e.actor_id for e in events])
    return [
        SegmentEventOut(
            at=e.at,
            actor=names.get(e.actor_id) if e.actor_id else "system",
            action=e.action,
            snapshot=e.snapshot,
            comment=e.comment,
        )  # fmt: skip
        for e in events
    ]


@router.get("/review-queue")
def get_review_queue(
    session: SessionDep, user: CurrentUser, limit: int = Query(default=200, ge=1, le=1000)
) -> list[QueueItemOut]:
    items = review_queue(session, limit)
    outs = _segment_outs(session, [it.segment for it in items])
    return [
        QueueItemOut(segment=o, video_name=it.video.name, rank=it.rank, reason=it.reason)
        for o, it in zip(outs, items, strict=True)
    ]


# -- export / import ------------------------------------------------------------------------


def attachment(filename: str) -> str:
    """Content-Disposition for any name: an ASCII stand-in in `filename` (quotes, backslashes,
    control and non-ASCII characters replaced) and the exact name in RFC 5987 `filename*`."""
    fallback = "".join(c if " " <= c <= "~" and c not in '"\\' else "_" for c in filename)
    return f"attachment; filename=\"{fallback}\"; filename*=UTF-8''{quote(filename, safe='')}"


def _not_a_json_number(constant: str) -> float:
    # Python's json reads NaN and Infinity, which JSON does not have: no value may hold them.
    raise LabellingError(f"file: {constant} is not a JSON number")


@router.get("/videos/{video_id}/export")
def export_video(
    video_id: DbId,
    session: SessionDep,
    user: CurrentUser,
    format: ExportFormat = "csv",
    status_: list[SegmentStatus] | None = Query(default=None, alias="status"),
) -> Response:
    video = segments.get_video(session, video_id)
    statuses = status_ or [SegmentStatus.ACCEPTED]
    filename = f"{video.name}.{EXPORT_SUFFIX[format]}"
    headers = {"Content-Disposition": attachment(filename)}
    if format == "csv":
        return Response(export.export_csv(session, video, statuses), media_type="text/csv",
                        headers=headers)  # fmt: skip
    document = (export.export_json if format == "json" else export.export_coco)(
        session, video, statuses
    )
    return JSONResponse(document, headers=headers)


@router.post("/import", status_code=status.HTTP_201_CREATED)
async def import_file(
    file: UploadFile,
    session: SessionDep,
    user: CurrentUser,
    format: ExportFormat = Query(description="what the file holds"),
    name: str | None = Query(default=None, max_length=128, description="new video name"),
    mode: exchange.ImportMode | None = Query(
        default=None,
        description="new: a new video (JSON, COCO: the default); merge: the file's labels onto "
        "the existing video, but those it holds already (CSV: the default); replace: as merge, "
        "after withdrawing the video's imported labels still under review",
    ),
) -> ImportOut:
    raw = await file.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise LabellingError("file: must be UTF-8 text") from error
    if format == "csv":
        placed = exchange.import_csv(
            session, text, importer=user, mode=mode or exchange.ImportMode.MERGE
        )
        return _import_out(sorted(placed), list(placed.values()))
    try:
        document = json.loads(text, parse_constant=_not_a_json_number)
    except json.JSONDecodeError as error:
        raise LabellingError(f"file: not JSON ({error.msg} at line {error.lineno})") from error
    if not isinstance(document, dict):
        raise LabellingError("file: JSON must be an object")
    importer = exchange.import_json if format == "json" else exchange.import_coco
    imported = importer(
        session, document, name, importer=user, mode=mode or exchange.ImportMode.NEW
    )
    return _import_out([imported.video.name], [imported.placed])


def _import_out(videos: list[str], placed: list[exchange.Placed]) -> ImportOut:
    return ImportOut(
        videos=videos,
        segments=sum(p.created for p in placed),
        already_there=sum(p.already_there for p in placed),
        replaced=sum(p.replaced for p in placed),
    )


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
        key for key, label in taxonomy.labels.items()
        if label.decision(video.mode) == Decision.EMERGENCY
    }  # fmt: skip
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
        blob = frame_keypoints(session, video.id, frame)
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
