"""Training and evaluation data from the database: recordings (videos with their frames) and the
accepted fine-label segments on them, turned into the detection code's FrameData.

Also imports URFD sequences into the database as videos with accepted `import` segments, so the
gold set (videos with split 'test') and retraining both read one place.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.taxonomy import TaxonomyLabel
from backend.models.videos import Frame, Split, Video
from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.datasets import urfd
from vigil.observation import Observation
from vigil.skeleton import (
    SkeletonFrame,
    decode_depth,
    decode_floor,
    decode_keypoints,
    encode_floor,
    encode_keypoints,
)
from vigil.taxonomy import DEFAULT_TAXONOMY
from worker.training.data import FrameData, sequence_arrays

# URFD official label -> fine label (walking mode: the first two are Emergency, the rest Normal).
URFD_FALL_LABELS = {0.0: "falling", 1.0: "lying_on_floor", -1.0: "standing"}
URFD_ADL_LABELS = {0.0: "sitting_down", 1.0: "lying_down_deliberately", -1.0: "walking"}


def _runs(values: list[str | None]) -> list[tuple[int, int, str]]:
    runs, start = [], 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            if values[start] is not None:
                runs.append((start, i - 1, values[start]))
            start = i
    return runs


def import_urfd(
    session: Session, names: Iterable[str], split: Split, directory=None
) -> list[Video]:
    """Store URFD sequences (real data) as videos with accepted import segments; idempotent."""
    names = list(names)
    existing = {v.name: v for v in session.scalars(select(Video).where(Video.name.in_(
        [f"urfd/{n}" for n in names])))}  # fmt: skip
    videos = []
    for seq in urfd.load(directory, [n for n in names if f"urfd/{n}" not in existing]):
        video = Video(
            name=f"urfd/{seq.name}", source="urfd", generated=False, mode=TransportMode.WALKING,
            camera="kinect-cam0", fps=urfd.FPS, split=split, frame_count=len(seq),
        )  # fmt: skip
        session.add(video)
        session.flush()
        session.execute(
            Frame.__table__.insert(),
            [
                {
                    "video_id": video.id,
                    "index": i,
                    "ts": float(t),
                    "keypoints": encode_keypoints(k),
                    "floor": encode_floor(f),  # URFD's own depth features (vigil.datasets.urfd)
                }  # fmt: skip
                for i, (k, t, f) in enumerate(
                    zip(seq.keypoints, seq.timestamps, seq.floor, strict=True)
                )
            ],
        )
        mapping = URFD_FALL_LABELS if seq.is_fall else URFD_ADL_LABELS
        fine = [None if np.isnan(v) else mapping[float(v)] for v in seq.urfd_label]
        for first, last, key in _runs(fine):
            session.add(
                AnnotationSegment(
                    video_id=video.id,
                    first_frame=first,
                    last_frame=last,
                    label_key=key,
                    taxonomy_version=DEFAULT_TAXONOMY.version,
                    status=SegmentStatus.ACCEPTED,
                    source=SegmentSource.IMPORT,
                )  # fmt: skip
            )
        videos.append(video)
    session.flush()
    for name in names:
        if f"urfd/{name}" in existing:
            video = existing[f"urfd/{name}"]
            video.split = split
            videos.append(video)
    return videos


def label_decisions(session: Session, mode: TransportMode) -> dict[tuple[int, str], Decision]:
    """(taxonomy version, fine label key) -> class in `mode`, from the database's taxonomy."""
    column = {
        TransportMode.WALKING: TaxonomyLabel.walking,
        TransportMode.WHEELCHAIR: TaxonomyLabel.wheelchair,
        TransportMode.COMBINED: TaxonomyLabel.combined,
    }[TransportMode(mode)]
    rows = session.execute(select(TaxonomyLabel.version, TaxonomyLabel.key, column)).all()
    mapping = {(v, k): Decision(d) for v, k, d in rows}
    for label in DEFAULT_TAXONOMY.labels:  # the seeded copy, should the table be empty
        mapping.setdefault((DEFAULT_TAXONOMY.version, label.key), label.decision(mode))
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


def frame_data(
    session: Session, videos: list[Video], mode: TransportMode, feature_set: str = "full"
) -> FrameData:
    """Frames of the videos in order, targets from accepted segments (-1 where none).

    A sequence is positive (a fall) when any of its frames is labelled Emergency. The data hash
    covers every frame and label used, so equal hashes mean equal training data.
    """
    if not videos:
        raise ValueError("no labelled recordings to build a data set from")
    classes = MODE_CLASSES[TransportMode(mode)]
    decisions = label_decisions(session, mode)
    digest = hashlib.sha256()
    feats, targets, groups, times, usable, positive, generated = [], [], [], [], [], [], False
    recordings = []
    for i, video in enumerate(videos):
        rows = session.execute(
            select(Frame.index, Frame.ts, Frame.keypoints, Frame.depth, Frame.floor)
            .where(Frame.video_id == video.id)
            .order_by(Frame.index)
        ).all()
        if not rows:
            raise ValueError(f"video {video.name} has no frames")
        keypoints = np.stack([decode_keypoints(r.keypoints) for r in rows])
        has_depth = any(r.depth is not None for r in rows)
        depth = (
            np.stack([decode_depth(r.depth) if r.depth is not None else
                      np.full(keypoints.shape[1], np.nan, np.float32) for r in rows])
            if has_depth else None
        )  # fmt: skip
        floor = np.stack([decode_floor(r.floor) for r in rows])
        ts = np.array([r.ts for r in rows], np.float64)
        ts = ts - ts[0]
        no_depth = np.full(keypoints.shape[1], np.nan, np.float32)
        observations = tuple(
            Observation(
                float(ts[j]),
                [SkeletonFrame(keypoints[j], depth[j] if depth is not None else no_depth,
                               float(ts[j]), floor[j])]
                if (keypoints[j, :, 2] > 0).any() else [],
                j,
            )
            for j in range(len(rows))
        )  # fmt: skip
        index_of = {r.index: j for j, r in enumerate(rows)}
        target = np.full(len(rows), -1, np.int64)
        segments = session.scalars(
            select(AnnotationSegment)
            .where(
                AnnotationSegment.video_id == video.id,
                AnnotationSegment.status == SegmentStatus.ACCEPTED,
            )
            .order_by(AnnotationSegment.id)
        ).all()
        for seg in segments:
            decision = decisions.get((seg.taxonomy_version, seg.label_key))
            if decision is None:
                raise ValueError(
                    f"video {video.name}: label {seg.label_key!r} is not in taxonomy "
                    f"version {seg.taxonomy_version}"
                )
            for frame_index in range(seg.first_frame, seg.last_frame + 1):
                j = index_of.get(frame_index)
                if j is not None:
                    target[j] = classes.index(decision)
        digest.update(json.dumps([video.name, len(rows)]).encode())
        digest.update(keypoints.tobytes())
        digest.update(target.tobytes())
        features, seen = sequence_arrays(list(observations), feature_set)
        feats.append(features)
        targets.append(target)
        groups.append(np.full(len(rows), i))
        times.append(ts)
        usable.append(seen)
        recordings.append(observations)
        positive.append(bool(np.any(target == classes.index(Decision.EMERGENCY))))
        generated = generated or video.generated
    return FrameData(
        names=[v.name for v in videos],
        is_positive_sequence=np.array(positive),
        features=np.concatenate(feats),
        target=np.concatenate(targets),
        group=np.concatenate(groups),
        timestamps=np.concatenate(times),
        usable=np.concatenate(usable),
        mode=TransportMode(mode),
        data_sha256=digest.hexdigest(),
        generated=generated,
        recordings=tuple(recordings),
    )
