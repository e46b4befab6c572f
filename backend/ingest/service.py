"""Robot ingest: transports, frame storage (deduplicated by robot + sequence) and the alarms
that robot decisions raise. The caller commits; acknowledgements go out only after that."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np
from sqlalchemy import insert, select
from sqlalchemy.orm import Session

from backend.alarms.service import DecisionEvidence, raise_or_update
from backend.models._types import utcnow
from backend.models.alarms import Alarm, AlarmKind
from backend.models.robots import Robot, Transport
from backend.models.videos import Frame, Video
from backend.security import robot_token_matches
from vigil.classes import Decision, TransportMode
from vigil.protocol import FrameRecord, Hello, TransportEnd, TransportStart
from vigil.skeleton import encode_depth, encode_keypoints

ALARM_KIND_OF_DECISION = {Decision.EMERGENCY: AlarmKind.EMERGENCY, Decision.PAUSE: AlarmKind.PAUSE}


class RobotAuthError(Exception):
    pass


def authenticate(session: Session, hello: Hello) -> Robot:
    robot = session.get(Robot, hello.robot_id)
    if robot is None or not robot_token_matches(robot.token_hash, hello.token):
        raise RobotAuthError("unknown robot or wrong or revoked token")
    robot.agent_version = hello.agent_version
    robot.running_model_version = hello.running_model
    robot.last_seen_at = utcnow()
    return robot


def _video_name(robot_id: str, transport_id: str | None) -> str:
    return f"robot/{robot_id}/{transport_id or 'untracked'}"


def start_transport(session: Session, robot: Robot, message: TransportStart) -> Transport:
    transport = session.get(Transport, message.transport_id)
    if transport is None:
        transport = Transport(
            id=message.transport_id,
            robot_id=robot.id,
            mode=message.mode,
            patient=message.patient,
            location=message.location,
            started_at=datetime.fromtimestamp(message.ts, UTC),
        )
        session.add(transport)
    elif transport.robot_id != robot.id:
        raise ValueError(f"transport_id {message.transport_id} belongs to another robot")
    return transport


def end_transport(session: Session, robot: Robot, message: TransportEnd) -> None:
    transport = session.get(Transport, message.transport_id)
    if transport is not None and transport.robot_id == robot.id and transport.ended_at is None:
        transport.ended_at = datetime.fromtimestamp(message.ts, UTC)


def _video_for(session: Session, robot: Robot, transport: Transport | None) -> Video:
    name = _video_name(robot.id, transport.id if transport else None)
    video = session.scalars(select(Video).where(Video.name == name)).first()
    if video is None:
        video = Video(
            name=name,
            source="robot",
            mode=transport.mode if transport else TransportMode.WALKING,
            camera=f"{robot.id}/front",
            location=transport.location if transport else None,
            person=transport.patient if transport else None,
            transport_id=transport.id if transport else None,
            robot_id=robot.id,
            frame_count=0,
        )
        session.add(video)
        session.flush()
    return video


@dataclass
class IngestResult:
    highest_seq: int | None
    stored: int
    duplicates: int
    alarms: list[Alarm] = field(default_factory=list)
    new_alarm_ids: set[int] = field(default_factory=set)


def _depth_blob(depth: list[float | None] | None) -> bytes | None:
    if depth is None:
        return None
    return encode_depth(np.array([np.nan if v is None else v for v in depth], np.float32))


def store_frames(session: Session, robot: Robot, frames: Sequence[FrameRecord]) -> IngestResult:
    seqs = [f.seq for f in frames]
    existing = set(
        session.scalars(
            select(Frame.seq).where(Frame.robot_id == robot.id, Frame.seq.in_(seqs))
        ).all()
    )
    fresh: dict[int, FrameRecord] = {}
    for frame in frames:
        if frame.seq not in existing:
            fresh.setdefault(frame.seq, frame)
    duplicates = len(frames) - len(fresh)

    transports: dict[str | None, Transport | None] = {}
    videos: dict[str | None, Video] = {}
    rows = []
    alarms: dict[int, Alarm] = {}
    new_alarm_ids: set[int] = set()
    for frame in sorted(fresh.values(), key=lambda f: f.seq):
        key = frame.transport_id
        if key not in transports:
            transports[key] = session.get(Transport, key) if key else None
            videos[key] = _video_for(session, robot, transports[key])
        video = videos[key]
        rows.append(
            {
                "video_id": video.id,
                "index": video.frame_count,
                "ts": frame.ts,
                "robot_id": robot.id,
                "seq": frame.seq,
                "keypoints": encode_keypoints(np.asarray(frame.keypoints, np.float32)),
                "depth": _depth_blob(frame.depth),
                "decision": frame.decision,
                "scores": {k.value: v for k, v in frame.scores.items()} or None,
                "model_version": frame.model_version,
                "threshold": frame.threshold,
                "delay_ms": frame.delay_ms,
                "shadow_decision": frame.shadow.decision if frame.shadow else None,
                "shadow_scores": (
                    {k.value: v for k, v in frame.shadow.scores.items()} if frame.shadow else None
                ),
                "shadow_model_version": frame.shadow.model_version if frame.shadow else None,
            }
        )
        video.frame_count += 1
        kind = ALARM_KIND_OF_DECISION.get(frame.decision)
        if kind is not None:
            evidence = DecisionEvidence(
                seq=frame.seq,
                ts=frame.ts,
                model_version=frame.model_version,
                threshold=frame.threshold,
                delay_ms=frame.delay_ms,
                video_id=video.id,
            )
            alarm, is_new = raise_or_update(session, robot, transports[key], kind, evidence)
            alarms[alarm.id] = alarm
            if is_new:
                new_alarm_ids.add(alarm.id)
    if rows:
        session.execute(insert(Frame), rows)
    highest = max(seqs) if seqs else None
    if highest is not None and (robot.last_seq is None or highest > robot.last_seq):
        robot.last_seq = highest
    robot.last_seen_at = utcnow()
    return IngestResult(highest, len(rows), duplicates, list(alarms.values()), new_alarm_ids)
