"""Labelling API: export of a video's labels and import of a file."""

from __future__ import annotations

import json
from typing import Literal

from fastapi import APIRouter, Query, Response, UploadFile, status
from fastapi.responses import JSONResponse

from backend.api.downloads import attachment
from backend.deps import CurrentUser, DbId, SessionDep
from backend.labelling import exchange, export, segments
from backend.labelling.errors import LabellingError
from backend.labelling.schemas import (
    ImportOut,
)
from backend.models.annotations import SegmentStatus

router = APIRouter(prefix="/api/labelling", tags=["labelling"])

ExportFormat = Literal["csv", "json", "coco"]
#: Each format its own file name: a JSON and a COCO export of one video never overwrite each other.
EXPORT_SUFFIX: dict[str, str] = {"csv": "csv", "json": "json", "coco": "coco.json"}


# -- export / import ------------------------------------------------------------------------


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
        return Response(
            export.export_csv(session, video, statuses), media_type="text/csv", headers=headers
        )
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
