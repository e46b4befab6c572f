"""Labelling queries, in one place."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from sqlalchemy import ColumnElement, Row, func, select
from sqlalchemy.orm import Session

from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.taxonomy import TaxonomyLabel
from backend.models.users import User
from backend.models.videos import Frame, Split, Video
from backend.storage.frame_reads import of_video
from vigil.classes import TransportMode
from vigil.skeleton import N_FLOOR, N_KEYPOINTS, decode_depth, decode_floor, decode_keypoints

LIVE = tuple(s for s in SegmentStatus if s != SegmentStatus.DELETED)


def videos_matching(
    session: Session,
    mode: TransportMode | None = None,
    split: Split | None = None,
    source: str | None = None,
    person: str | None = None,
    scope: ColumnElement[bool] | None = None,
) -> list[Video]:
    """Videos by name, narrowed by whichever filters are given; `scope`: the caller's wards
    (backend.wards.videos_visible)."""
    query = select(Video).order_by(Video.name)
    if scope is not None:
        query = query.where(scope)
    for column, value in (
        (Video.mode, mode),
        (Video.split, split),
        (Video.source, source),
        (Video.person, person),
    ):
        if value is not None:
            query = query.where(column == value)
    return list(session.scalars(query))


def video_segments(
    session: Session, video_id: int, statuses: Iterable[SegmentStatus] = LIVE
) -> list[AnnotationSegment]:
    return list(
        session.scalars(
            select(AnnotationSegment)
            .where(
                AnnotationSegment.video_id == video_id,
                AnnotationSegment.status.in_(list(statuses)),
            )
            .order_by(AnnotationSegment.first_frame, AnnotationSegment.id)
        )
    )


def video_frames(
    session: Session, video: Video
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(indices, keypoints (n, 25, 3), depth (n, 25), floor (n, 3)) of a whole video, NaN where
    unknown."""
    rows = session.execute(
        select(Frame.index, Frame.keypoints, Frame.depth, Frame.floor)
        .where(*of_video(session, video))
        .order_by(Frame.index)
    ).all()
    indices = np.array([r[0] for r in rows], np.int64)
    keypoints = np.stack([decode_keypoints(r[1]) for r in rows]) if rows else np.zeros((0, 25, 3))
    depth = np.full((len(rows), N_KEYPOINTS), np.nan, np.float32)
    for i, row in enumerate(rows):
        if row[2] is not None:
            depth[i] = decode_depth(row[2])
    floor = np.stack([decode_floor(r[3]) for r in rows]) if rows else np.zeros((0, N_FLOOR))
    return indices, keypoints, depth, floor


def frame_timestamps(session: Session, video: Video) -> dict[int, float]:
    return dict(
        session.execute(select(Frame.index, Frame.ts).where(*of_video(session, video))).all()
    )


def usernames(session: Session, ids: Iterable[int | None]) -> dict[int, str]:
    wanted = {i for i in ids if i is not None}
    if not wanted:
        return {}
    return dict(session.execute(select(User.id, User.username).where(User.id.in_(wanted))).all())


def user_by_name(session: Session, username: str) -> User | None:
    return session.scalars(select(User).where(User.username == username)).first()


def progress_by_video(session: Session) -> dict[int, dict[str, int]]:
    """video id -> {status: number of segments, "labelled_frames": frames covered by a
    segment that is not rejected (overlaps counted once)}."""
    out: dict[int, dict[str, int]] = {}
    covered: dict[int, set[int]] = {}
    rows = session.execute(
        select(
            AnnotationSegment.video_id,
            AnnotationSegment.status,
            AnnotationSegment.first_frame,
            AnnotationSegment.last_frame,
        ).where(AnnotationSegment.status != SegmentStatus.DELETED)
    ).all()
    for video_id, status, first, last in rows:
        entry = out.setdefault(video_id, {})
        entry[str(status)] = entry.get(str(status), 0) + 1
        if status != SegmentStatus.REJECTED:
            covered.setdefault(video_id, set()).update(range(first, last + 1))
    for video_id, frames in covered.items():
        out[video_id]["labelled_frames"] = len(frames)
    return out


#: The name under which a video's imported labels (a dataset's own, e.g. URFD's) take part in
#: agreement, so that an annotator can be compared with them.
IMPORTED_LABELS = "(imported)"


def agreement_annotators(session: Session, video_id: int) -> list[str]:
    """Who can be compared on a video: its annotators by name, then the imported labels."""
    live = video_segments(session, video_id)
    drawn = {s.annotator_id for s in live if s.annotator_id and s.source != SegmentSource.IMPORT}
    names = sorted(usernames(session, drawn).values())
    if any(s.source == SegmentSource.IMPORT for s in live):
        names.append(IMPORTED_LABELS)
    return names


def agreement_spans(session: Session, video_id: int, who: str) -> list[tuple[int, int, str]] | None:
    """(first, last, label) of one side of an agreement: the segments a user drew (live, not
    rejected), or the imported labels (whoever imported them); None when no such user exists."""
    live = [s for s in video_segments(session, video_id) if s.status != SegmentStatus.REJECTED]
    if who == IMPORTED_LABELS:
        chosen = [s for s in live if s.source == SegmentSource.IMPORT]
    else:
        owner = user_by_name(session, who)
        if owner is None:
            return None
        chosen = [
            s for s in live if s.annotator_id == owner.id and s.source != SegmentSource.IMPORT
        ]
    return [(s.first_frame, s.last_frame, s.label_key) for s in chosen]


def facet_values(session: Session, column) -> list[str]:
    """The distinct non-empty values of a video column, sorted (the list filters)."""
    return sorted(v for v in session.scalars(select(column).distinct()) if v)


def video_modes(session: Session, video_ids: Iterable[int]) -> dict[int, TransportMode]:
    return dict(
        session.execute(select(Video.id, Video.mode).where(Video.id.in_(set(video_ids)))).all()
    )


def frame_keypoints(session: Session, video: Video, index: int) -> bytes | None:
    return session.scalar(
        select(Frame.keypoints).where(*of_video(session, video), Frame.index == index)
    )


TIMELINE_COLUMNS = (
    Frame.index,
    Frame.ts,
    Frame.seq,
    Frame.keypoints,
    Frame.depth,
    Frame.floor,
    Frame.decision,
    Frame.scores,
    Frame.model_version,
    Frame.threshold,
    Frame.delay_ms,
    Frame.shadow_decision,
    Frame.shadow_model_version,
)


def frames_between(session: Session, video: Video, first: int, last: int) -> list[Row]:
    """The video's frames first..last (inclusive), in order: rows of TIMELINE_COLUMNS."""
    return list(
        session.execute(
            select(*TIMELINE_COLUMNS)
            .where(*of_video(session, video), Frame.index >= first, Frame.index <= last)
            .order_by(Frame.index)
        )
    )


def taxonomy_labels(
    session: Session, version: int | None
) -> tuple[int | None, list[TaxonomyLabel]]:
    """(version, its labels in order); the latest version when `version` is None."""
    if version is None:
        version = session.scalar(select(func.max(TaxonomyLabel.version)))
    labels = session.scalars(
        select(TaxonomyLabel)
        .where(TaxonomyLabel.version == version)
        .order_by(TaxonomyLabel.position)
    ).all()
    return version, list(labels)
