"""Robot ingest: transports, frame storage (deduplicated by robot + sequence) and the alarms
that robot decisions raise. The caller commits; acknowledgements go out only after that."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.alarms import service as alarms
from backend.alarms.service import DecisionEvidence, fold_evidence, raise_or_update
from backend.ingest.context import (
    ALARM_KIND_OF_DECISION,
    IngestContext,
    RobotState,
    TransportState,
    VideoState,
    video_name,
)
from backend.ingest.received import ROW_TAIL_START, ReceivedFrame, shows_person
from backend.models._types import utcnow
from backend.models.alarms import Alarm, AlarmKind, AlarmState
from backend.models.robots import Robot, Transport
from backend.models.videos import Frame, Video
from backend.registry import queries as registry_queries
from backend.security import robot_token_matches
from vigil.classes import TransportMode
from vigil.protocol import BehaviourChanged, DetectionStatus, Hello, TransportEnd, TransportStart

log = logging.getLogger(__name__)

DEFAULT_FPS = 30.0  # a robot transport whose transport_start gave no frame rate


class RobotAuthError(Exception):
    pass


def authenticate(session: Session, hello: Hello) -> Robot:
    """The robot of a hello whose token matches (reads only: the welcome never waits on a
    stalled write; what the hello says is stored by the frame writer, `apply_hello`)."""
    robot = session.get(Robot, hello.robot_id)
    if robot is None or not robot_token_matches(robot.token_hash, hello.token):
        raise RobotAuthError("unknown robot or wrong or revoked token")
    return robot


def apply_hello(robot: RobotState, hello: Hello) -> None:
    """What a robot says at every connect, stored by the frame writer after the welcome: all
    of it through the writer's robot state, written back with the flush (one statement per
    column group however many robots reconnect at once)."""
    robot.running_model_version = hello.running_model
    robot.running_model_sha256 = hello.running_sha256
    robot.running_model_changed = True
    robot.fleet_news = True
    robot.last_seen_at = utcnow()
    # Said at every connect; an agent that says nothing feeds keypoints only (None).
    inputs = list(hello.inputs) if hello.inputs is not None else None
    robot.agent = (hello.agent_version, inputs)


def token_still_valid(session: Session, hello: Hello) -> bool:
    token_hash = session.scalar(select(Robot.token_hash).where(Robot.id == hello.robot_id))
    return robot_token_matches(token_hash, hello.token)


def registry_sha256_for(session: Session, hello: Hello) -> dict[str, str] | None:
    """What the welcome tells a robot whose hello gave a sha256: the registry's sha256 of the
    versions it named (running and fallback) that the registry knows; None for older agents."""
    if hello.running_sha256 is None and hello.fallback_sha256 is None:
        return None
    versions = {v for v in (hello.running_model, hello.fallback_model) if v is not None}
    return registry_queries.sha256_of_versions(session, versions)


class TransportNotOwned(ValueError):
    """A message names a transport of another robot (closed with CLOSE_FORBIDDEN)."""

    def __init__(self, transport_id: str) -> None:
        super().__init__(f"transport_id {transport_id} belongs to another robot")


def transport_owners(session: Session, transport_ids: Iterable[str]) -> dict[str, str]:
    """transport id -> the robot it belongs to, for those of `transport_ids` that exist."""
    ids = list(transport_ids)
    if not ids:
        return {}
    rows = session.execute(select(Transport.id, Transport.robot_id).where(Transport.id.in_(ids)))
    return {row.id: row.robot_id for row in rows}


def start_transport(session: Session, robot: Robot, message: TransportStart) -> Transport:
    transport = session.get(Transport, message.transport_id)
    if transport is None:
        # A robot carries one patient at a time: starting a transport ends any it left open.
        for stale in session.scalars(
            select(Transport).where(Transport.robot_id == robot.id, Transport.ended_at.is_(None))
        ):
            stale.ended_at = datetime.fromtimestamp(message.ts, UTC)
        transport = Transport(
            id=message.transport_id,
            robot_id=robot.id,
            mode=message.mode,
            patient=message.patient,
            location=message.location,
            started_at=datetime.fromtimestamp(message.ts, UTC),
            fps=message.fps,
            # The patient-not-seen grace starts now on the server's clock (started_at is the
            # robot's, which may be off).
            last_patient_at=utcnow(),
        )
        session.add(transport)
    elif transport.robot_id != robot.id:
        raise TransportNotOwned(message.transport_id)
    elif message.fps is not None and transport.fps != message.fps:
        # Sent again (a reconnect) with the real frame rate: the recording follows.
        transport.fps = message.fps
        video = session.scalars(
            select(Video).where(Video.name == video_name(robot.id, transport.id))
        ).first()
        if video is not None:
            video.fps = message.fps
    return transport


def end_transport(session: Session, robot: Robot, message: TransportEnd) -> None:
    """Mark the transport ended; its unresolved alarms stay latched but are pushed again (after
    the commit) so the board can say "transport ended N min ago"."""
    transport = session.get(Transport, message.transport_id)
    if transport is None or transport.robot_id != robot.id or transport.ended_at is not None:
        return
    transport.ended_at = datetime.fromtimestamp(message.ts, UTC)
    unresolved = session.scalars(
        select(Alarm).where(Alarm.transport_id == transport.id, Alarm.state != AlarmState.RESOLVED)
    ).unique()
    for alarm in unresolved:
        alarms.publish(session, alarm)


def _video_for(
    session: Session,
    robot: Robot | RobotState,
    transport: Transport | TransportState | None,
    context: IngestContext,
) -> Video | VideoState:
    name = video_name(robot.id, transport.id if transport else None)
    video = context.videos.get(name)
    if video is None:
        video = session.scalars(select(Video).where(Video.name == name)).first()
    if video is None:
        video = Video(
            name=name,
            source="robot",
            mode=transport.mode if transport else TransportMode.WALKING,
            camera=f"{robot.id}/front",
            location=transport.location if transport else None,
            fps=(transport.fps if transport else None) or DEFAULT_FPS,
            person=transport.patient if transport else None,
            transport_id=transport.id if transport else None,
            robot_id=robot.id,
            frame_count=0,
        )
        session.add(video)
        session.flush()
    context.videos[name] = video
    return video


@dataclass
class IngestResult:
    highest_seq: int | None
    stored: int
    duplicates: int
    alarms: list[Alarm] = field(default_factory=list)
    new_alarm_ids: set[int] = field(default_factory=set)


#: Capture times closer than this are one frame sent again (floats through JSON and the column).
SAME_FRAME_TS_S = 1e-3


def _existing_seqs(
    session: Session, robot: Robot | RobotState, seqs: list[int], context: IngestContext
) -> dict[int, float]:
    """seq -> capture time of the frames of `seqs` already stored or gathered."""
    pending = context.pending_seqs.setdefault(robot.id, {})
    # robot.last_seq is the highest stored sequence number (kept in the same transaction as
    # the rows), so a batch entirely above it cannot hold a stored frame: skip the query.
    if robot.last_seq is not None and min(seqs) <= robot.last_seq:
        stored = session.execute(
            select(Frame.seq, Frame.ts).where(Frame.robot_id == robot.id, Frame.seq.in_(seqs))
        ).all()
        return dict(stored) | pending
    return pending


def store_frames(
    session: Session,
    robot: Robot | RobotState,
    frames: Sequence[ReceivedFrame],
    context: IngestContext | None = None,
) -> IngestResult:
    """Store the frames not stored yet and raise or update the alarms their decisions call for.

    With a shared `context` the rows are only gathered (the caller runs `context.flush_rows`);
    without one they are inserted before returning.
    """
    own_context = context is None
    context = context or IngestContext()
    seqs = [f.seq for f in frames]
    existing = _existing_seqs(session, robot, seqs, context)
    fresh: dict[int, ReceivedFrame] = {}
    reused: list[ReceivedFrame] = []  # a number used again for another frame (capture time)
    for frame in frames:
        if frame.seq not in existing:
            fresh.setdefault(frame.seq, frame)
        elif abs(existing[frame.seq] - frame.ts) > SAME_FRAME_TS_S:
            reused.append(frame)
    duplicates = len(frames) - len(fresh)
    if reused:
        log.warning(
            "robot %s sent %d frames under sequence numbers it had already used for other "
            "frames (seq %d..%d); they are not stored, and their Emergency or Pause decisions "
            "still raise alarms",
            robot.id,
            len(reused),
            reused[0].seq,
            reused[-1].seq,
        )

    now = utcnow()
    videos: dict[str | None, Video] = {}
    alarms: dict[tuple[str | None, AlarmKind], Alarm] = {}
    new_alarm_ids: set[int] = set()
    rows = context.rows
    pending = context.pending_seqs[robot.id]
    # Every transport the batch names must be this robot's; checked before anything of it is
    # gathered (the connection checks first, this is the last word inside the transaction).
    for key in {f.transport_id for f in frames if f.transport_id is not None}:
        transport = context.transport(session, key)
        if transport is not None and transport.robot_id != robot.id:
            raise TransportNotOwned(key)
    # A frame under a reused sequence number is not stored (the stored one stays), but a fall
    # it reports must still reach the nurse: its decision raises or updates the alarm.
    alarming_reused = [f for f in reused if f.decision in ALARM_KIND_OF_DECISION]
    for frame in sorted([*fresh.values(), *alarming_reused], key=lambda f: f.seq):
        key = frame.transport_id
        transport = context.transport(session, key)
        video = videos.get(key)
        if video is None:
            video = videos[key] = _video_for(session, robot, transport, context)
            if transport is not None:
                transport.last_frame_at = now
        if fresh.get(frame.seq) is frame:
            rows.append(
                (video.id, video.frame_count, frame.ts, robot.id, frame.seq)
                + frame[ROW_TAIL_START:]
            )
            pending[frame.seq] = frame.ts
            video.frame_count += 1
            video.cover(frame.ts, frame.ts)
            if (
                transport is not None
                and transport.last_patient_at != now
                and shows_person(frame.keypoints)
            ):
                transport.last_patient_at = now
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
            alarm = alarms.get((key, kind)) or context.open_alarms.get((robot.id, key or "", kind))
            if alarm is not None and alarm.state != AlarmState.RESOLVED:
                push = context.update_push_due(alarm.id, time.monotonic())
                fold_evidence(session, alarm, evidence, now, push=push)
            else:
                # Pending row updates cannot change which alarm is unresolved: no autoflush.
                with session.no_autoflush:
                    alarm, is_new = raise_or_update(session, robot, transport, kind, evidence)
                context.open_alarms[(robot.id, key or "", kind)] = alarm
                context.pushed_at[alarm.id] = time.monotonic()
                if is_new:
                    new_alarm_ids.add(alarm.id)
            alarms[(key, kind)] = alarm
    stored = len(fresh)
    if own_context:
        context.flush_rows(session)
    highest = max(seqs) if seqs else None
    if highest is not None and (robot.last_seq is None or highest > robot.last_seq):
        robot.last_seq = highest
    robot.last_seen_at = now
    unique_alarms = list({a.id: a for a in alarms.values()}.values())
    return IngestResult(highest, stored, duplicates, unique_alarms, new_alarm_ids)


def degraded_details(message: DetectionStatus) -> dict:
    """What the nurse board and the engineers read on a detection_degraded alarm."""
    return {
        "missing_inputs": list(message.missing_inputs),
        "reason": message.reason,
        "assigned_model": message.assigned_model,
        "running_model": message.running_model,
        "fallback": message.running_model is not None
        and message.running_model != message.assigned_model,
        "summary": degraded_summary(message),
        "status_ts": message.ts,
    }


def degraded_summary(message: DetectionStatus) -> str:
    words = {"depth": "depth", "floor": "floor measures", "keypoints": "keypoints"}
    missing = "no " + ("/".join(words.get(m, m) for m in message.missing_inputs) or "an input")
    if not message.missing_inputs and message.assigned_model:
        # Degraded with every input there: the robot refused its model (its file is not the
        # registry's) and says what decides instead (robot_agent.pipeline.refuse_model).
        missing = f"model {message.assigned_model} refused"
    if message.running_model and message.running_model != message.assigned_model:
        running = f"running keypoints-only fallback {message.running_model}"
    elif message.running_model:
        running = f"{message.running_model} runs on what is left"
    else:
        running = "no fallback model"
    return f"{missing}, {running}"


def apply_behaviour(robot: RobotState, message: BehaviourChanged) -> None:
    """The robot's last reported behaviour, for the fleet page (written back with the flush)."""
    robot.last_seen_at = utcnow()
    since = datetime.fromtimestamp(message.since, UTC)
    robot.behaviour = (message.state.value, since, message.reason)


def apply_detection_status(
    session: Session,
    robot: Robot | RobotState,
    message: DetectionStatus,
    context: IngestContext,
) -> list[Alarm]:
    """degraded: raise (or update) the robot's detection_degraded alarm for the transport;
    recovered: clear every unresolved one of the robot. Returns the alarms changed.

    The status travels in the robot's outbox and may be sent again after a reconnect: a status
    no newer than the one the robot's latest degraded alarm last saw is a replay and is ignored,
    so a replayed "degraded" cannot reopen what a later "recovered" cleared.
    """
    kind = AlarmKind.DETECTION_DEGRADED
    latest = session.scalars(
        select(Alarm)
        .where(Alarm.robot_id == robot.id, Alarm.kind == kind)
        .order_by(Alarm.raised_at.desc(), Alarm.id.desc())
        .limit(1)
    ).first()
    seen_ts = (latest.details or {}).get("status_ts") if latest is not None else None
    if seen_ts is not None and message.ts <= seen_ts:
        return []
    now = utcnow()
    if not message.degraded:
        cleared = []
        for alarm in session.scalars(
            select(Alarm).where(
                Alarm.robot_id == robot.id, Alarm.kind == kind, Alarm.state != AlarmState.RESOLVED
            )
        ).unique():
            alarm.details = {
                **(alarm.details or {}),
                "status_ts": message.ts,
                "recovered_reason": message.reason,
            }
            running = message.running_model or message.assigned_model or "its model"
            note = f"detection recovered: {running} has every input it needs"
            if message.reason:
                note += f" ({message.reason})"
            cleared.append(alarms.clear(session, alarm, now, note))
        return cleared
    transport = context.transport(session, message.transport_id)
    if transport is not None and transport.robot_id != robot.id:
        raise TransportNotOwned(message.transport_id)
    video = context.videos.get(video_name(robot.id, transport.id if transport else None))
    evidence = DecisionEvidence(
        seq=robot.last_seq,  # the status follows this frame in the robot's stream
        ts=message.ts,
        model_version=message.running_model,
        video_id=video.id if video is not None else None,
    )
    with session.no_autoflush:
        alarm, _ = raise_or_update(session, robot, transport, kind, evidence)
    alarm.details = degraded_details(message)
    return [alarm]
