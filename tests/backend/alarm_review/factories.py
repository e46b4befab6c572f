"""Rows for alarm-review tests: a robot with a transport video and classified frames."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
from sqlalchemy.orm import Session

from backend.models import Alarm, AlarmKind, AlarmState, Frame, Robot, Transport, Video
from backend.models.alarms import PRIORITY_OF_KIND
from vigil.skeleton import encode_keypoints

T0 = datetime(2026, 3, 2, 9, 0, tzinfo=UTC)


def robot_with_frames(session: Session, robot_id: str = "r1", n: int = 100, fps: float = 10.0):
    session.add(Robot(id=robot_id, ward="A"))
    session.add(Transport(id=f"{robot_id}-t1", robot_id=robot_id, mode="walking", patient="P-7"))
    video = Video(
        name=f"{robot_id}-t1",
        source="robot",
        mode="walking",
        fps=fps,
        transport_id=f"{robot_id}-t1",
        robot_id=robot_id,
    )
    session.add(video)
    session.flush()
    base = T0.timestamp()
    for i in range(n):
        emergency = 0.9 if 50 <= i < 70 else 0.1
        session.add(
            Frame(
                video_id=video.id,
                index=i,
                ts=base + i / fps,
                robot_id=robot_id,
                seq=1000 + i,
                keypoints=encode_keypoints(np.full((25, 3), [i, 2 * i, 1.0], np.float32)),
                decision="emergency" if emergency > 0.5 else "normal",
                scores={"normal": 1 - emergency, "emergency": emergency},
                model_version="m1",
                threshold=0.5,
                delay_ms=300,
            )
        )
    session.flush()
    return video


def alarm(session: Session, video: Video | None = None, **over) -> Alarm:
    fields = dict(
        kind=AlarmKind.EMERGENCY,
        state=AlarmState.OPEN,
        robot_id="r1",
        transport_id="r1-t1",
        transport_key="r1-t1",
        ward="A",
        patient="P-7",
        location="corridor 2",
        raised_at=T0 + timedelta(seconds=5),
        updated_at=T0 + timedelta(seconds=5),
        video_id=video.id if video else None,
        first_seq=1053,
        last_seq=1069,
        first_frame_ts=T0.timestamp() + 5.3,
        last_frame_ts=T0.timestamp() + 6.9,
        model_version="m1",
        threshold=0.5,
        delay_ms=300,
    )
    fields.update(over)
    fields.setdefault("priority", PRIORITY_OF_KIND[AlarmKind(fields["kind"])])
    row = Alarm(**fields)
    session.add(row)
    session.flush()
    return row
