"""Training and evaluation data from the database: recordings (videos with their frames) and the
accepted fine-label segments on them, turned into the detection code's FrameData.

Recordings get into the database through the server domain's importers (URFD:
backend.labelling.importers.urfd); the gold set (videos with split 'test') and retraining both
read them here.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.labelling.taxonomy import load_taxonomy, taxonomy_versions
from backend.models.annotations import AnnotationSegment, SegmentStatus
from backend.models.videos import Frame, Split, Video
from backend.storage.frame_reads import of_video
from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.observation import Observation
from vigil.segments import frame_segments
from vigil.skeleton import N_FLOOR, N_KEYPOINTS, SkeletonFrame, decode_many
from vigil.taxonomy import DEFAULT_TAXONOMY
from worker.training.data import FrameData, Recording, build_rows


def label_decisions(session: Session, mode: TransportMode) -> dict[tuple[int, str], Decision]:
    """(taxonomy version, fine label key) -> class in `mode`, from the database's taxonomy."""
    taxonomies = [load_taxonomy(session, v) for v in taxonomy_versions(session)]
    mapping = {}
    for taxonomy in [*taxonomies, DEFAULT_TAXONOMY]:  # the seeded copy, should the table be empty
        for label in taxonomy.labels:
            mapping.setdefault((taxonomy.version, label.key), label.decision(mode))
    return mapping


def labelled_videos(
    session: Session, mode: TransportMode, split: Split | None = None, ids: list[int] | None = None
) -> list[Video]:
    """Videos of `mode` with at least one accepted segment, optionally of one split or ids."""
    query = (
        select(Video)
        .where(Video.mode == mode)
        .where(
            Video.id.in_(
                select(AnnotationSegment.video_id).where(
                    AnnotationSegment.status == SegmentStatus.ACCEPTED
                )
            )
        )
        .order_by(Video.id)
    )
    if split is not None:
        query = query.where(Video.split == split)
    if ids is not None:
        query = query.where(Video.id.in_(ids))
    return list(session.scalars(query))


def accepted_segments(session: Session, video_ids: list[int]) -> dict[int, list[AnnotationSegment]]:
    """Accepted segments of the videos (one query per 500 videos), per video in id order."""
    out: dict[int, list[AnnotationSegment]] = {}
    for start in range(0, len(video_ids), 500):
        for seg in session.scalars(
            select(AnnotationSegment)
            .where(
                AnnotationSegment.video_id.in_(video_ids[start : start + 500]),
                AnnotationSegment.status == SegmentStatus.ACCEPTED,
            )
            .order_by(AnnotationSegment.video_id, AnnotationSegment.id)
        ):
            out.setdefault(seg.video_id, []).append(seg)
    return out


def db_recordings(
    session: Session, videos: list[Video], mode: TransportMode
) -> tuple[list[Recording], str]:
    """The database source: each video's stored frames as the robot's camera would give them
    (one person where a pose was found, with the depth and floor measures stored beside it),
    targets from the accepted segments by the one rule for overlaps
    (`vigil.segments.frame_segments`, which the exports use too); and a hash that covers
    every frame and label used, so equal hashes mean equal training data."""
    if not videos:
        raise ValueError("no labelled recordings to build a data set from")
    classes = MODE_CLASSES[TransportMode(mode)]
    decisions = label_decisions(session, mode)
    segments_of = accepted_segments(session, [v.id for v in videos])
    digest = hashlib.sha256()
    recordings = []
    for video in videos:
        rows = session.execute(
            select(Frame.index, Frame.ts, Frame.keypoints, Frame.depth, Frame.floor)
            .where(*of_video(session, video))
            .order_by(Frame.index)
        ).all()
        if not rows:
            raise ValueError(f"video {video.name} has no frames")
        indices, stamps, kp_blobs, depth_blobs, floor_blobs = zip(*rows, strict=True)
        keypoints = decode_many(kp_blobs, N_KEYPOINTS * 3).reshape(len(rows), N_KEYPOINTS, 3)
        has_depth = any(blob is not None for blob in depth_blobs)
        depth = decode_many(depth_blobs, N_KEYPOINTS) if has_depth else None
        floor = decode_many(floor_blobs, N_FLOOR)
        ts = np.array(stamps, np.float64)
        ts = ts - ts[0]
        no_depth = np.full(keypoints.shape[1], np.nan, np.float32)
        seen_any = (keypoints[:, :, 2] > 0).any(axis=1)
        observations = tuple(
            Observation(
                float(ts[j]),
                [
                    SkeletonFrame(
                        keypoints[j],
                        depth[j] if depth is not None else no_depth,
                        float(ts[j]),
                        floor[j],
                    )
                ]
                if seen_any[j]
                else [],
                j,
            )
            for j in range(len(rows))
        )
        winners = frame_segments(max(indices) + 1, segments_of.get(video.id, []))
        target = np.full(len(rows), -1, np.int64)
        for j, frame_index in enumerate(indices):
            seg = winners[frame_index] if frame_index >= 0 else None
            if seg is None:
                continue
            decision = decisions.get((seg.taxonomy_version, seg.label_key))
            if decision is None:
                raise ValueError(
                    f"video {video.name}: label {seg.label_key!r} is not in taxonomy "
                    f"version {seg.taxonomy_version}"
                )
            target[j] = classes.index(decision)
        digest.update(json.dumps([video.name, len(rows)]).encode())
        digest.update(keypoints.tobytes())
        digest.update(target.tobytes())
        recordings.append(Recording(video.name, observations, target, video.generated))
    return recordings, digest.hexdigest()


def frame_data(
    session: Session, videos: list[Video], mode: TransportMode, feature_set: str = "full"
) -> FrameData:
    """Training rows of the videos in order (the one builder, `build_rows`, fed by the database
    source), targets from accepted segments (-1 where none)."""
    recordings, digest = db_recordings(session, videos, mode)
    return build_rows(recordings, mode, digest, feature_set)
