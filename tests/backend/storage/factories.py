"""Crafted rows for the storage tests: robots, robot videos with frames at chosen times, alarms,
labels, splits and a registered model's lineage."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.ingest.bulk import insert_frame_rows
from backend.models import (
    Alarm,
    AlarmKind,
    AnnotationSegment,
    Frame,
    ModelVersion,
    Robot,
    SegmentStatus,
    Split,
    Video,
)
from backend.models.alarms import PRIORITY_OF_KIND
from backend.storage.policy import DAY_S
from vigil.skeleton import encode_depth, encode_floor, encode_keypoints

NOW = time.time()
#: Start of the UTC day that holds the cutoff of a 30-day policy at NOW.
CUTOFF_DAY = (NOW - 30 * DAY_S) // DAY_S * DAY_S


def policy_settings(**changes) -> SimpleNamespace:
    values = dict(
        retention_days=30,
        retention_alarm_before_s=60,
        retention_alarm_after_s=30,
        retention_downsample_fps=0,
        retention_downsample_days=60,
        retention_chunk_rows=50,
        retention_chunk_pause_ms=0,
        partitions_ahead_days=2,
    )
    values.update(changes)
    return SimpleNamespace(**values)


def robot(session: Session, robot_id: str) -> str:
    if session.get(Robot, robot_id) is None:
        session.add(Robot(id=robot_id, ward="ward-a"))
        session.flush()
    return robot_id


def robot_video(
    session: Session,
    name: str,
    robot_id: str | None,
    times: list[float],
    first_seq: int = 0,
    split: Split = Split.UNASSIGNED,
    fps: float = 10.0,
) -> Video:
    if robot_id is not None:
        robot(session, robot_id)
    video = Video(
        name=name,
        source="robot" if robot_id else "urfd",
        mode="walking",
        fps=fps,
        robot_id=robot_id,
        split=split,
        frame_count=len(times),
    )
    session.add(video)
    session.flush()
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    rows = []
    for i, ts in enumerate(times):
        rows.append(
            (
                video.id,
                i,
                ts,
                robot_id,
                None if robot_id is None else first_seq + i,
                encode_keypoints(rng.normal(size=(25, 3)).astype(np.float32)),
                encode_depth(rng.uniform(0.5, 4, 25).astype(np.float32)) if i % 3 else None,
                encode_floor(rng.normal(size=3).astype(np.float32)),
                "normal",
                '{"normal": 0.9, "emergency": 0.1}',
                "m-1",
                0.5,
                300,
                None,
                None,
                None,
            )
        )
    insert_frame_rows(session, rows)
    if times:
        video.cover(min(times), max(times))  # as every writer of frames does
    return video


def alarm(session: Session, robot_id: str, first_ts: float, last_ts: float) -> Alarm:
    row = Alarm(
        kind=AlarmKind.EMERGENCY,
        priority=PRIORITY_OF_KIND[AlarmKind.EMERGENCY],
        robot_id=robot_id,
        ward="ward-a",
        first_frame_ts=first_ts,
        last_frame_ts=last_ts,
        state="resolved",
    )
    session.add(row)
    session.flush()
    return row


def label(session: Session, video: Video, first: int, last: int, key: str = "walking") -> None:
    session.add(
        AnnotationSegment(
            video_id=video.id,
            first_frame=first,
            last_frame=last,
            label_key=key,
            taxonomy_version=1,
            status=SegmentStatus.ACCEPTED,
        )
    )
    session.flush()


def model_trained_on(session: Session, names: list[str]) -> None:
    session.add(
        ModelVersion(
            version="m-lineage",
            mode="walking",
            kind="rf",
            file_path="x",
            sha256="0" * 64,
            manifest={},
            lineage={"training_videos": names},
        )
    )
    session.flush()


def frame_rows(session: Session) -> dict[int, tuple]:
    """id -> (video_id, robot_id, ts, index) of every stored frame."""
    return {
        r.id: (r.video_id, r.robot_id, r.ts, r.index)
        for r in session.execute(
            select(Frame.id, Frame.video_id, Frame.robot_id, Frame.ts, Frame.index)
        )
    }


def live_row(video_id: int, robot_id: str, seq: int, ts: float) -> tuple:
    """One frame row as the ingest writes it (backend.ingest.bulk.FRAME_COLUMNS)."""
    keypoints = encode_keypoints(np.full((25, 3), seq % 97, np.float32))
    return (
        video_id,
        seq,
        ts,
        robot_id,
        seq,
        keypoints,
        None,
        None,
        "normal",
        '{"normal": 1.0}',
        "m-1",
        0.5,
        300,
        None,
        None,
        None,
    )
