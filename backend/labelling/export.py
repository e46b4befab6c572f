"""Export a video's labels: CSV (one row per frame), Vigil JSON (everything), COCO keypoints.

Segments exported are those with the requested statuses (accepted by default: training data).
Where exported segments overlap, the one updated last wins the frame (CSV and COCO): the one
rule of `vigil.segments.frame_segments`, which training uses too.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np
from sqlalchemy.orm import Session

from backend.labelling.queries import frame_timestamps, usernames, video_frames, video_segments
from backend.labelling.taxonomy import load_taxonomy
from backend.models.annotations import AnnotationSegment, SegmentStatus
from backend.models.videos import Video
from vigil.formats.coco import COCO17
from vigil.segments import overlap_order, segment_labels
from vigil.skeleton import INDEX

JSON_FORMAT = "vigil-labels"
JSON_VERSION = 1
CSV_COLUMNS = ("video", "frame", "ts", "label_key", "walking", "wheelchair", "combined")
COCO_BODY25 = [INDEX[name] for name in COCO17]
COCO_SKELETON = [
    [16, 14],
    [14, 12],
    [17, 15],
    [15, 13],
    [12, 13],
    [6, 12],
    [7, 13],
    [6, 7],
    [6, 8],
    [7, 9],
    [8, 10],
    [9, 11],
    [2, 3],
    [1, 2],
    [1, 3],
    [2, 4],
    [3, 5],
    [4, 6],
    [5, 7],
]
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
    "image_width",
    "image_height",
    "frame_count",
    "intrinsics",
)


def _segments(session: Session, video: Video, statuses) -> list[AnnotationSegment]:
    segments = video_segments(session, video.id, statuses)
    return sorted(segments, key=overlap_order)


def _per_frame(session: Session, video: Video, statuses) -> list[str | None]:
    return segment_labels(video.frame_count, video_segments(session, video.id, statuses))


def export_csv(session: Session, video: Video, statuses=(SegmentStatus.ACCEPTED,)) -> str:
    taxonomy = load_taxonomy(session)
    labels = _per_frame(session, video, statuses)
    timestamps = frame_timestamps(session, video)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for index, label in enumerate(labels):
        known = taxonomy.get(label) if label else None
        ts = timestamps.get(index, index / video.fps)
        writer.writerow(
            [video.name, index, f"{ts:.6f}", label or ""]
            + [known.decision(mode).value if known else "" for mode in CSV_COLUMNS[4:]]
        )
    return out.getvalue()


def _number(value: float) -> float | None:
    return None if math.isnan(value) else round(float(value), 6)


def export_json(session: Session, video: Video, statuses=(SegmentStatus.ACCEPTED,)) -> dict:
    indices, keypoints, depth, floor = video_frames(session, video)
    timestamps = frame_timestamps(session, video)
    segments = _segments(session, video, statuses)
    names = usernames(
        session, [s.annotator_id for s in segments] + [s.reviewer_id for s in segments]
    )
    return {
        "format": JSON_FORMAT,
        "version": JSON_VERSION,
        "taxonomy_version": load_taxonomy(session).version,
        "video": {field: _plain(getattr(video, field)) for field in VIDEO_FIELDS},
        "frames": [
            {
                "index": int(index),
                "ts": timestamps[int(index)],
                "keypoints": np.round(keypoints[i].astype(np.float64), 6).tolist(),
                "depth": None if np.all(np.isnan(depth[i])) else [_number(v) for v in depth[i]],
                "floor": None if np.all(np.isnan(floor[i])) else [_number(v) for v in floor[i]],
            }
            for i, index in enumerate(indices)
        ],
        "segments": [
            {
                "first_frame": s.first_frame,
                "last_frame": s.last_frame,
                "label_key": s.label_key,
                "status": str(s.status),
                "annotator": names.get(s.annotator_id),
                "reviewer": names.get(s.reviewer_id),
                "review_comment": s.review_comment,
            }
            for s in sorted(segments, key=lambda s: (s.first_frame, s.last_frame, s.label_key))
        ],
    }


def _plain(value):
    return value.value if hasattr(value, "value") else value


def export_coco(session: Session, video: Video, statuses=(SegmentStatus.ACCEPTED,)) -> dict:
    """COCO keypoints: one image per frame, one person annotation per frame with a pose.
    Visibility 2 for a detected keypoint, 0 for a missing one (BODY_25 confidence is dropped)."""
    taxonomy = load_taxonomy(session)
    labels = _per_frame(session, video, statuses)
    indices, keypoints, _, _ = video_frames(session, video)
    images, annotations = [], []
    for i, index in enumerate(indices):
        index = int(index)
        label = labels[index] if index < len(labels) else None
        images.append(
            {
                "id": index + 1,
                "label_key": label,
                "file_name": f"{video.name}/{index:06d}.jpg",
                "frame_index": index,
                "width": video.image_width or 0,
                "height": video.image_height or 0,
            }
        )
        points = keypoints[i][COCO_BODY25]
        visible = points[:, 2] > 0
        if not visible.any():
            continue
        flat = []
        for (x, y, _), seen in zip(points, visible, strict=True):
            flat += [round(float(x), 6), round(float(y), 6), 2] if seen else [0, 0, 0]
        xs, ys = points[visible, 0], points[visible, 1]
        known = taxonomy.get(label) if label else None
        annotations.append(
            {
                "id": index + 1,
                "image_id": index + 1,
                "category_id": 1,
                "keypoints": flat,
                "num_keypoints": int(visible.sum()),
                "bbox": [
                    float(xs.min()),
                    float(ys.min()),
                    float(xs.max() - xs.min()),
                    float(ys.max() - ys.min()),
                ],
                "area": float((xs.max() - xs.min()) * (ys.max() - ys.min())),
                "iscrowd": 0,
                "attributes": {
                    "label_key": label,
                    "decision": known.decision(video.mode).value if known else None,
                },
            }
        )
    return {
        "info": {
            "description": f"Vigil export of video {video.name}",
            "video": {field: _plain(getattr(video, field)) for field in VIDEO_FIELDS},
            "taxonomy_version": taxonomy.version,
        },
        "images": images,
        "annotations": annotations,
        "categories": [
            {
                "id": 1,
                "name": "person",
                "supercategory": "person",
                "keypoints": list(COCO17),
                "skeleton": COCO_SKELETON,
            }
        ],
    }
