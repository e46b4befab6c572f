"""Import what `export` writes: Vigil JSON (new video), COCO keypoints (new video), CSV (labels
onto existing videos).

A file is untrusted input from whoever uploads it, so import never takes the fields that decide
what reaches training or the gold set from it (issue 18): a new video's split is `unassigned`
(only an admin changes it: `PATCH /api/labelling/videos/{id}`) and its source is `import`; a
file may mark its recording as generated but never make generated data pass for real. Every
imported label becomes a `pending` segment with source `import`, the importer as its annotator
and no reviewer or review comment, whatever status the file says: it is reviewed like any other,
by someone else.

Importing into a video that exists is explicit (`ImportMode`): `merge` adds the file's labels
the video lacks, so importing the same file twice changes nothing; `replace` first withdraws the
video's imported labels still under review. A new video's name must be free (`new`)."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from sqlalchemy.orm import Session

from backend.labelling import validation
from backend.labelling.errors import Conflict, LabellingError
from backend.labelling.export import CSV_COLUMNS, JSON_FORMAT
from backend.labelling.queries import video_segments
from backend.labelling.segments import SegmentDraft, create_segment, delete_segment
from backend.labelling.status import EDITABLE
from backend.labelling.store import add_video, video_by_name
from backend.labelling.validation import (
    CocoAnnotation,
    CocoImage,
    FrameHead,
    SegmentRecord,
    VideoMeta,
    validated,
)
from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.users import User
from backend.models.videos import Split, Video
from vigil.formats.coco import coco17_to_body25
from vigil.segments import label_runs
from vigil.skeleton import N_FLOOR, N_KEYPOINTS

#: `Video.source` of every video created by an import (the file's own claim is not kept).
IMPORTED_SOURCE = "import"
#: The status of every imported segment: proposed, waiting for a reviewer.
IMPORTED_ENTRY = "propose"  # SEGMENT.entries: an exchange file's labels wait for review


class ImportMode(StrEnum):
    NEW = "new"  # a new video (JSON, COCO); its name must be free
    MERGE = "merge"  # the file's labels onto the existing video, but those it already holds
    REPLACE = "replace"  # as merge, after withdrawing its imported labels still under review


#: The `code` of the 409 answer to a new-video import whose name is taken (with `video` and the
#: `modes` that would import into it instead).
VIDEO_EXISTS = "video_exists"


@dataclass(frozen=True, slots=True)
class Placed:
    """What an import did to one video's labels."""

    created: int = 0
    already_there: int = 0
    replaced: int = 0


@dataclass(frozen=True, slots=True)
class Imported:
    video: Video
    placed: Placed


def _place(
    session: Session,
    video: Video,
    runs: list[tuple[int, int, str]],
    importer: User | None,
    mode: ImportMode,
) -> Placed:
    """The file's labels onto a video: a label the video already holds live (same frames, same
    label, not rejected) is not added again."""
    live = video_segments(session, video.id)
    replaced = 0
    if mode == ImportMode.REPLACE:
        if importer is None:
            raise LabellingError("mode: replace needs a signed-in importer")
        for segment in live:
            if segment.source == SegmentSource.IMPORT and segment.status in EDITABLE:
                delete_segment(session, segment, importer)
                replaced += 1
        live = video_segments(session, video.id)
    held = {
        (s.first_frame, s.last_frame, s.label_key)
        for s in live
        if s.status != SegmentStatus.REJECTED
    }
    created = 0
    for run in runs:
        if tuple(run) in held:
            continue
        _add_segment(session, video, SegmentDraft(*run), importer)
        held.add(tuple(run))
        created += 1
    return Placed(created=created, already_there=len(runs) - created, replaced=replaced)


def _target(session: Session, video: Video, mode: ImportMode, frame_count: int) -> Video | None:
    """The existing video an import of `video`'s name goes into (merge, replace), or None for a
    new video. Refuses a taken name for `new` and a missing video or other frames for the rest."""
    existing = video_by_name(session, video.name)
    if mode == ImportMode.NEW:
        if existing is not None:
            raise Conflict(
                f"video: {video.name!r} exists; import with mode=merge to add the labels it "
                "lacks, mode=replace to replace its imported labels under review, or pass another "
                "name",
                # For a client to offer the choice in its own words (the annotator's import).
                code=VIDEO_EXISTS,
                video=video.name,
                modes=[ImportMode.MERGE.value, ImportMode.REPLACE.value],
            )
        return None
    if existing is None:
        raise LabellingError(f"mode: {mode} needs an existing video, and {video.name!r} is not one")
    if existing.frame_count != frame_count:
        raise LabellingError(
            f"frames: the file has {frame_count} frames, video {video.name!r} has "
            f"{existing.frame_count}: not the same recording"
        )
    return existing


def _video_from_meta(meta: object, name: str | None) -> Video:
    """The video a file describes, every field checked (validation.VideoMeta); `name` (the
    query parameter) replaces the file's."""
    if not isinstance(meta, dict):
        raise LabellingError("video: must be an object")
    if name is not None:
        validation.video_name(name)
    checked = validated(VideoMeta, meta, "video")
    if not (name or checked.name):
        raise LabellingError("video.name: missing")
    return Video(
        name=name or checked.name,
        source=IMPORTED_SOURCE,
        # The cautious direction only: a file can say "generated", never "real".
        generated=checked.generated is True,
        mode=checked.mode,
        camera=checked.camera,
        location=checked.location,
        fps=checked.fps or 30.0,
        person=checked.person,
        split=Split.UNASSIGNED,
        image_width=checked.image_width or None,
        image_height=checked.image_height or None,
        intrinsics=checked.intrinsics.model_dump() if checked.intrinsics else None,
    )


def _add_segment(
    session: Session, video: Video, draft: SegmentDraft, importer: User | None
) -> AnnotationSegment:
    return create_segment(
        session, video, draft, importer, source=SegmentSource.IMPORT, entry=IMPORTED_ENTRY
    )


def _numbers(frames: list, key: str, shape: tuple[int, ...], optional: bool) -> np.ndarray:
    """frames[i][key] of every frame as float32 (n, *shape); an optional field may be missing
    or null (all NaN) and hold nulls (NaN). Each error names the frame and the field."""
    out = np.full((len(frames), *shape), np.nan, np.float32)
    for i, frame in enumerate(frames):
        value = frame.get(key) if isinstance(frame, dict) else None
        if value is None:
            if optional:
                continue
            raise LabellingError(f"frames[{i}].{key}: missing")
        try:
            row = np.array(
                [np.nan if v is None else v for v in value] if optional else value, np.float64
            )
        except (TypeError, ValueError) as error:
            raise LabellingError(f"frames[{i}].{key}: not numbers ({error})") from error
        if row.shape != shape:
            raise LabellingError(f"frames[{i}].{key}: must have shape {list(shape)}")
        # Beyond float32's range a number would be stored as an infinity JSON cannot carry.
        limit = np.finfo(np.float32).max
        if np.isinf(row).any() or (np.abs(row[np.isfinite(row)]) > limit).any():
            raise LabellingError(f"frames[{i}].{key}: numbers must lie within float32 range")
        if not optional and np.isnan(row).any():
            raise LabellingError(f"frames[{i}].{key}: must be numbers, not null")
        out[i] = row
    return out


def import_json(
    session: Session,
    document: dict,
    name: str | None = None,
    importer: User | None = None,
    mode: ImportMode = ImportMode.NEW,
) -> Imported:
    if document.get("format") != JSON_FORMAT:
        raise LabellingError(f"format: expected {JSON_FORMAT!r}, got {document.get('format')!r}")
    video = _video_from_meta(document.get("video"), name)
    frames = document.get("frames")
    if not isinstance(frames, list) or not frames:
        raise LabellingError("frames: must be a non-empty list")
    heads = validated(list[FrameHead], frames, "frames")
    indices = [h.index for h in heads]
    timestamps = [h.ts for h in heads]
    keypoints = _numbers(frames, "keypoints", (N_KEYPOINTS, 3), optional=False)
    depth = _numbers(frames, "depth", (N_KEYPOINTS,), optional=True)
    floor = _numbers(frames, "floor", (N_FLOOR,), optional=True)
    if min(indices) < 0 or len(set(indices)) != len(indices):
        raise LabellingError("frames: indices must be unique and not negative")
    records = validated(list[SegmentRecord], document.get("segments") or [], "segments")
    existing = _target(session, video, mode, max(indices) + 1)
    if existing is None:
        add_video(session, video, keypoints, timestamps, depth, indices, floor)
    else:
        video = existing
    # status, reviewer and review_comment in the file are ignored (see the module doc).
    runs = [(r.first_frame, r.last_frame, r.label_key) for r in records]
    return Imported(video, _place(session, video, runs, importer, mode))


def import_coco(
    session: Session,
    document: dict,
    name: str | None = None,
    importer: User | None = None,
    mode: ImportMode = ImportMode.NEW,
) -> Imported:
    info = document.get("info") or {}
    if not isinstance(info, dict):
        raise LabellingError("info: must be an object")
    meta = info.get("video") or {}
    if not isinstance(meta, dict):
        raise LabellingError("info.video: must be an object")
    if not meta.get("name") and not name:
        raise LabellingError("info.video.name: missing (or pass a name)")
    images = document.get("images")
    if not isinstance(images, list) or not images:
        raise LabellingError("images: must be a non-empty list")
    video = _video_from_meta(meta, name)
    checked_images = validated(list[CocoImage], images, "images")
    annotations = validated(list[CocoAnnotation], document.get("annotations") or [], "annotations")
    by_image = {a.image_id: a for a in annotations}
    frame_of = {
        id(im): im.id - 1 if im.frame_index is None else im.frame_index for im in checked_images
    }
    if len(set(frame_of.values())) != len(checked_images):
        raise LabellingError("images: two images have the same frame number")
    indices, points, labels = [], [], []
    for image in sorted(checked_images, key=lambda im: frame_of[id(im)]):
        annotation = by_image.get(image.id)
        coco = np.zeros((17, 3), np.float32)
        if annotation is not None:
            coco = np.array(annotation.keypoints, np.float32).reshape(17, 3)
            coco[:, 2] = (coco[:, 2] > 0).astype(np.float32)
        indices.append(frame_of[id(image)])
        points.append(coco)
        labels.append(image.label_key)
    keypoints = coco17_to_body25(np.stack(points))
    existing = _target(session, video, mode, max(indices) + 1)
    if existing is None:
        add_video(session, video, keypoints, [i / video.fps for i in indices], None, indices)
    else:
        video = existing
    frame_label = [None] * video.frame_count
    for index, label in zip(indices, labels, strict=True):
        frame_label[index] = label or None
    return Imported(video, _place(session, video, label_runs(frame_label), importer, mode))


def import_csv(
    session: Session,
    text: str,
    importer: User | None = None,
    mode: ImportMode = ImportMode.MERGE,
) -> dict[str, Placed]:
    """Labels onto videos that exist (by name), merged or replacing; what was placed per video."""
    if mode == ImportMode.NEW:
        raise LabellingError("mode: a CSV carries labels only, not frames: use merge or replace")
    # newline="": the csv module splits lines itself, so a lone \r ends a line as in any editor.
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        header = tuple(reader.fieldnames or ())
        if header[:4] != CSV_COLUMNS[:4]:
            raise LabellingError(f"csv: header must start with {','.join(CSV_COLUMNS[:4])}")
        per_video: dict[str, dict[int, str | None]] = {}
        for row in reader:
            try:
                frame = int(row["frame"])
            except (TypeError, ValueError) as error:
                raise LabellingError(
                    f"csv line {reader.line_num}: frame must be an integer"
                ) from error
            per_video.setdefault(row["video"], {})[frame] = row["label_key"] or None
    except csv.Error as error:
        # line_num counts the lines parsed so far; the one that failed is the next.
        raise LabellingError(f"csv line {reader.line_num + 1}: {error}") from error
    placed: dict[str, Placed] = {}
    for name, labels in per_video.items():
        video = video_by_name(session, name)
        if video is None:
            raise LabellingError(f"csv: video {name!r} does not exist; import its frames first")
        outside = [f for f in labels if not 0 <= f < video.frame_count]
        if outside:
            raise LabellingError(
                f"csv: video {name!r} has frames 0..{video.frame_count - 1}, not {outside[0]}"
            )
        frame_label = [labels.get(i) for i in range(video.frame_count)]
        placed[name] = _place(session, video, label_runs(frame_label), importer, mode)
    return placed
