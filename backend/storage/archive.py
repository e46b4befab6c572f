"""Parquet archives of videos (pyarrow): one file per video with every stored frame (keypoints,
depth and floor blobs, decision, scores, shadow decision, model version, threshold, delay) and
its fine label, the video's attributes and accepted segments in the file's metadata, and a
manifest beside it with the file's sha256.

An archive can be imported again: the frames (bit for bit what was exported) and, when the
video has none, its segments come back, so it can be labelled or used as training data
(`RetrainParams.archive_ids`). Importing checks the sha256 first and adds nothing to a video
that already has its frames.
"""

from __future__ import annotations

import hashlib
import json
import re
from datetime import UTC, datetime
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
from sqlalchemy import insert, select
from sqlalchemy.orm import Session

from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.robots import Transport
from backend.models.storage import FrameArchive
from backend.models.videos import Frame, Split, Video
from backend.storage import queries
from vigil.segments import overlap_order, segment_labels

FORMAT = "vigil-frames-archive/1"
SCHEMA = pa.schema(
    [
        ("index", pa.int32()),
        ("ts", pa.float64()),
        ("robot_id", pa.string()),
        ("seq", pa.int64()),
        ("keypoints", pa.binary()),
        ("depth", pa.binary()),
        ("floor", pa.binary()),
        ("decision", pa.string()),
        ("scores", pa.string()),  # JSON text
        ("model_version", pa.string()),
        ("threshold", pa.float64()),
        ("delay_ms", pa.int32()),
        ("shadow_decision", pa.string()),
        ("shadow_scores", pa.string()),
        ("shadow_model_version", pa.string()),
        ("label", pa.string()),  # fine label of an accepted segment covering the frame
    ]
)
VIDEO_FIELDS = (
    "name",
    "source",
    "generated",
    "mode",
    "camera",
    "location",
    "fps",
    "person",
    "split",
    "transport_id",
    "robot_id",
    "frame_count",
    "image_width",
    "image_height",
    "intrinsics",
    "rgb_crop",
    "rgb_frame_offset",
)
FRAME_FIELDS = (
    "index",
    "ts",
    "robot_id",
    "seq",
    "keypoints",
    "depth",
    "floor",
    "decision",
    "scores",
    "model_version",
    "threshold",
    "delay_ms",
    "shadow_decision",
    "shadow_scores",
    "shadow_model_version",
)
JSON_FIELDS = ("scores", "shadow_scores")


class ArchiveError(ValueError):
    pass


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "video"


def _labels(segments: list[AnnotationSegment], indices: list[int]) -> list[str | None]:
    """Each frame's label by the one rule for overlapping segments (`vigil.segments`, which the
    CSV and COCO exports and the training rows use): the segment updated last wins."""
    per_frame = segment_labels(max(indices, default=-1) + 1, segments)
    return [per_frame[i] if i >= 0 else None for i in indices]


def export_video(
    session: Session, video: Video, directory: Path, created_by_id: int | None = None
) -> FrameArchive:
    frames = queries.video_frames(session, video.id)
    # In the overlap rule's order, so the segments imported again (in this order) win the same
    # frames.
    segments = sorted(queries.video_segments(session, video.id), key=overlap_order)
    columns: dict[str, list] = {name: [] for name in FRAME_FIELDS}
    for frame in frames:
        for name in FRAME_FIELDS:
            value = getattr(frame, name)
            if name in JSON_FIELDS and value is not None:
                value = json.dumps(value)
            columns[name].append(value)
    columns["label"] = _labels(segments, columns["index"])
    video_meta = {k: getattr(video, k) for k in VIDEO_FIELDS}
    segment_meta = [
        {
            "first_frame": s.first_frame,
            "last_frame": s.last_frame,
            "label_key": s.label_key,
            "taxonomy_version": s.taxonomy_version,
            "source": s.source,
            "model_version": s.model_version,
        }
        for s in segments
    ]
    table = pa.table(columns, schema=SCHEMA).replace_schema_metadata(
        {
            "vigil": json.dumps(
                {"format": FORMAT, "video": video_meta, "segments": segment_meta}, default=str
            )
        }
    )
    directory.mkdir(parents=True, exist_ok=True)
    stem = f"{_slug(video.name)}-v{video.id}"
    path = directory / f"{stem}.parquet"
    pq.write_table(table, path, compression="zstd")
    digest = sha256_of(path)
    ts = columns["ts"]
    manifest = {
        "format": FORMAT,
        "created_at": datetime.now(UTC).isoformat(),
        "file": path.name,
        "sha256": digest,
        "bytes": path.stat().st_size,
        "frames": len(frames),
        "labelled_frames": sum(1 for label in columns["label"] if label),
        "first_ts": min(ts) if ts else None,
        "last_ts": max(ts) if ts else None,
        "video": video_meta,
        "segments": len(segment_meta),
        "columns": SCHEMA.names,
    }
    manifest_path = directory / f"{stem}.manifest.json"
    manifest_path.write_text(json.dumps(manifest, indent=2, default=str))
    archive = FrameArchive(
        video_id=video.id,
        video_name=video.name,
        robot_id=video.robot_id,
        transport_id=video.transport_id,
        path=str(path),
        manifest_path=str(manifest_path),
        sha256=digest,
        frame_count=len(frames),
        labelled_frames=manifest["labelled_frames"],
        bytes=manifest["bytes"],
        first_ts=manifest["first_ts"],
        last_ts=manifest["last_ts"],
        created_by_id=created_by_id,
    )
    session.add(archive)
    session.flush()
    return archive


def export_transport(
    session: Session, transport_id: str, directory: Path, created_by_id: int | None = None
) -> list[FrameArchive]:
    if session.get(Transport, transport_id) is None:
        raise ArchiveError(f"transport {transport_id} not found")
    videos = session.scalars(select(Video).where(Video.transport_id == transport_id)).all()
    return [export_video(session, v, directory, created_by_id) for v in videos]


def read_archive(path: Path, expected_sha256: str | None = None) -> tuple[pa.Table, dict]:
    if expected_sha256 is not None and sha256_of(path) != expected_sha256:
        raise ArchiveError(f"{path.name}: sha256 does not match the manifest")
    table = pq.read_table(path)
    meta = json.loads((table.schema.metadata or {}).get(b"vigil", b"{}"))
    if meta.get("format") != FORMAT:
        raise ArchiveError(f"{path.name}: not a {FORMAT} file")
    return table, meta


def import_archive(session: Session, archive: FrameArchive) -> Video:
    """Bring an archived video's frames (and its segments, if it has none) back; idempotent."""
    table, meta = read_archive(Path(archive.path), archive.sha256)
    info = meta["video"]
    video = session.get(Video, archive.video_id) if archive.video_id else None
    if video is None:
        video = session.scalars(select(Video).where(Video.name == info["name"])).first()
    if video is None:
        fields = dict(info)
        fields["split"] = Split(fields.get("split") or Split.UNASSIGNED)
        if fields.get("transport_id") and session.get(Transport, fields["transport_id"]) is None:
            fields["transport_id"] = None
        video = Video(**fields)
        session.add(video)
        session.flush()
        archive.video_id = video.id
    if queries.frame_count(session, video.id) == 0 and table.num_rows:
        data = table.select(list(FRAME_FIELDS)).to_pylist()
        for row in data:
            row["video_id"] = video.id
            for name in JSON_FIELDS:
                if row[name] is not None:
                    row[name] = json.loads(row[name])
        session.execute(insert(Frame), data)
        stamps = [row["ts"] for row in data]
        video.cover(min(stamps), max(stamps))
    has_segments = session.scalar(
        select(AnnotationSegment.id).where(AnnotationSegment.video_id == video.id).limit(1)
    )
    if not has_segments and meta.get("segments"):
        session.add_all(
            AnnotationSegment(
                video_id=video.id,
                first_frame=s["first_frame"],
                last_frame=s["last_frame"],
                label_key=s["label_key"],
                taxonomy_version=s["taxonomy_version"],
                status=SegmentStatus.ACCEPTED,
                source=SegmentSource(s.get("source") or SegmentSource.IMPORT),
                model_version=s.get("model_version"),
            )
            for s in meta["segments"]
        )
    session.flush()
    return video
