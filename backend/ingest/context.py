"""What one writer transaction shares across every robot's work (`IngestContext`): the frame
rows gathered for one bulk insert, and robots, transports and videos loaded once as plain rows
and written back with one statement per table. The writer keeps it between flushes."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import bindparam, select, update
from sqlalchemy.orm import Session, lazyload

from backend.ingest.bulk import insert_frame_rows
from backend.ingest.bulk_update import one_round_trip, update_rows
from backend.models.alarms import Alarm, AlarmKind, AlarmState
from backend.models.robots import Robot, Transport
from backend.models.videos import Video, widened
from backend.unit_of_work import fleet_changed
from vigil.classes import Decision, TransportMode

ALARM_KIND_OF_DECISION = {Decision.EMERGENCY: AlarmKind.EMERGENCY, Decision.PAUSE: AlarmKind.PAUSE}
#: A continuing Emergency (or Pause) folds every frame's decision into its open alarm; the
#: boards get that update at most this often per alarm, and the last one always (a trailing
#: push by the writer); its state changes (raise, acknowledgement, escalation, end) go out at
#: once. Pushing every fold sent a fallen patient's alarm to every board, through Redis, ten
#: times a second per robot.
UPDATE_PUSH_S = 1.0
#: The trailing push waits this much longer than UPDATE_PUSH_S: a robot still deciding
#: Emergency folds its next frame within a tenth of a second, and the flush that folds it
#: pushes the alarm anyway. Pushed at the due time itself, a hundred such alarms went to every
#: board twice a second, once from the flush and once from a reload of their own.
TRAILING_PUSH_GRACE_S = 0.5

_robots = Robot.__table__
_AGENT_UPDATE = (
    update(_robots)
    .where(_robots.c.id == bindparam("robot"))
    .values(agent_version=bindparam("agent_version"), inputs=bindparam("inputs"))
)


def video_name(robot_id: str, transport_id: str | None) -> str:
    """The video a robot's frames of one transport are stored in."""
    return f"robot/{robot_id}/{transport_id or 'untracked'}"


@dataclass(slots=True)
class RobotState:
    """The robot columns the ingest path reads and writes, loaded without the ORM."""

    id: str
    ward: str
    token_hash: str | None
    last_seq: int | None
    last_seen_at: datetime | None = None
    running_model_version: str | None = None
    running_model_sha256: str | None = None
    running_model_changed: bool = False
    # (version, sha256) of the running model as stored, to tell news from a heartbeat
    # repeating it: only news goes to the fleet pages
    stored_model: tuple[str | None, str | None] = (None, None)
    # this flush changed the robot's fleet row otherwise: a hello (it (re)connected, says what
    # it feeds), a behaviour, detection degraded or recovered
    fleet_news: bool = False
    # A behaviour the robot reported in this flush: (state, since, reason), written back once.
    behaviour: tuple[str, datetime, str] | None = None
    # What its hello in this flush said: (agent version, inputs), written back once.
    agent: tuple[str | None, list[str] | None] | None = None


@dataclass(slots=True)
class TransportState:
    id: str
    robot_id: str
    mode: TransportMode
    patient: str | None
    location: str | None
    fps: float | None = None
    last_frame_at: datetime | None = None
    last_patient_at: datetime | None = None


@dataclass(slots=True)
class VideoState:
    id: int
    name: str
    frame_count: int
    initial_count: int = 0
    first_frame_ts: float | None = None
    last_frame_ts: float | None = None

    def cover(self, first_ts: float, last_ts: float) -> None:
        """Widen the frame time range (Video.cover, written back with frame_count)."""
        self.first_frame_ts, self.last_frame_ts = widened(
            self.first_frame_ts, self.last_frame_ts, first_ts, last_ts
        )


@dataclass
class IngestContext:
    """Rows and lookups shared by every robot's work in one writer transaction.

    Frame rows are gathered here and inserted with one bulk statement by `flush_rows`; robots,
    transports and videos are loaded once per transaction as plain rows (no ORM identity map)
    and their changed columns written back with one executemany per table.
    """

    robots: dict[str, RobotState | None] = field(default_factory=dict)
    transports: dict[str, TransportState | Transport | None] = field(default_factory=dict)
    videos: dict[str, VideoState | Video] = field(default_factory=dict)
    rows: list[tuple] = field(default_factory=list)  # laid out as bulk.FRAME_COLUMNS
    # robot id -> seq -> capture time of the frames gathered and not inserted yet
    pending_seqs: dict[str, dict[int, float]] = field(default_factory=dict)
    open_alarms: dict[tuple[str, str, AlarmKind], Alarm] = field(default_factory=dict)
    # The robots whose unresolved alarms `open_alarms` holds (loaded by `preload`).
    alarming: set[str] = field(default_factory=set)
    # alarm id -> monotonic time its last fold was pushed to the boards (kept between flushes)
    pushed_at: dict[int, float] = field(default_factory=dict)
    push_every_fold: bool = False  # a provisional card waits for its stored alarm
    # this flush: alarms pushed, and alarms whose folds were held back (alarm id -> when their
    # trailing push is due: the writer pushes them then, so the boards' last word is the last
    # fold)
    pushed: set[int] = field(default_factory=set)
    held_back: dict[int, float] = field(default_factory=dict)

    def update_push_due(self, alarm_id: int, now: float) -> bool:
        """Whether this fold of a decision into the alarm goes to the boards now."""
        last = self.pushed_at.get(alarm_id)
        if not self.push_every_fold and last is not None and now - last < UPDATE_PUSH_S:
            if alarm_id not in self.pushed:  # a push of this flush carries every fold of it
                self.held_back[alarm_id] = last + UPDATE_PUSH_S
            return False
        self.pushed_at[alarm_id] = now
        self.pushed.add(alarm_id)
        self.held_back.pop(alarm_id, None)
        return True

    def preload(
        self,
        session: Session,
        streams: set[tuple[str, str | None]],
        alarming_robots: set[str] | None = None,
    ) -> IngestContext:
        """Load, in a few queries, what the (robot id, transport id) streams of a flush touch;
        unresolved alarms only for `alarming_robots` (those with an Emergency or Pause frame
        in the flush; default: every robot)."""
        robot_ids = {robot_id for robot_id, _ in streams}
        transport_ids = {tid for _, tid in streams if tid is not None}
        missing = robot_ids - self.robots.keys()
        if missing:
            self.robots.update(dict.fromkeys(missing))
            for row in session.execute(
                select(
                    Robot.id,
                    Robot.ward,
                    Robot.token_hash,
                    Robot.last_seq,
                    Robot.running_model_version,
                    Robot.running_model_sha256,
                ).where(Robot.id.in_(missing))
            ):
                self.robots[row.id] = RobotState(
                    row.id,
                    row.ward,
                    row.token_hash,
                    row.last_seq,
                    stored_model=(row.running_model_version, row.running_model_sha256),
                )
        missing = transport_ids - self.transports.keys()
        if missing:
            self.transports.update(dict.fromkeys(missing))
            for row in session.execute(
                select(
                    Transport.id,
                    Transport.robot_id,
                    Transport.mode,
                    Transport.patient,
                    Transport.location,
                    Transport.fps,
                ).where(Transport.id.in_(missing))
            ):
                self.transports[row.id] = TransportState(*row)
        names = {video_name(robot_id, tid) for robot_id, tid in streams} - self.videos.keys()
        if names:
            for row in session.execute(
                select(
                    Video.id,
                    Video.name,
                    Video.frame_count,
                    Video.first_frame_ts,
                    Video.last_frame_ts,
                ).where(Video.name.in_(names))
            ):
                self.videos[row.name] = VideoState(
                    row.id,
                    row.name,
                    row.frame_count,
                    row.frame_count,
                    row.first_frame_ts,
                    row.last_frame_ts,
                )
        alarming = robot_ids if alarming_robots is None else alarming_robots & robot_ids
        self.alarming |= alarming
        if alarming:
            # Without the users, transport and dispositions the board shows: a robot deciding
            # Emergency brings its alarm into every flush, and the board needs them only for
            # the (held-back) pushes, loaded then for all at once (alarms.service.board_json).
            for alarm in session.scalars(
                select(Alarm)
                .where(
                    Alarm.robot_id.in_(alarming),
                    Alarm.state != AlarmState.RESOLVED,
                    Alarm.kind.in_(ALARM_KIND_OF_DECISION.values()),
                )
                .options(lazyload("*"))
            ):
                self.open_alarms[(alarm.robot_id, alarm.transport_key, alarm.kind)] = alarm
        return self

    def write_back(self, session: Session) -> None:
        """One bulk update per table and set of columns the flush changed, all sent in one
        round trip; the fleet pages are told (after the commit) of the robots whose row
        changed: a hello, another running model (not a heartbeat repeating it), a behaviour,
        detection degraded or recovered."""
        robots = [r for r in self.robots.values() if r is not None and r.last_seen_at]
        robot_table = Robot.__table__
        fleet_news = [
            r.id
            for r in robots
            if r.fleet_news
            or r.behaviour
            or (
                r.running_model_changed
                and (r.running_model_version, r.running_model_sha256) != r.stored_model
            )
        ]
        if fleet_news:
            fleet_changed(session, fleet_news)
        hellos = [
            {"robot": r.id, "agent_version": r.agent[0], "inputs": r.agent[1]}
            for r in robots
            if r.agent is not None
        ]
        if hellos:  # a JSON column: one executemany (a reconnect storm is one statement)
            session.execute(_AGENT_UPDATE, hellos)
        videos = [
            v
            for v in self.videos.values()
            if isinstance(v, VideoState) and v.frame_count != v.initial_count
        ]
        transports = [
            t
            for t in self.transports.values()
            if isinstance(t, TransportState) and t.last_frame_at is not None
        ]
        with one_round_trip(session):
            update_rows(
                session,
                robot_table,
                ("id", "last_seq", "last_seen_at"),
                [(r.id, r.last_seq, r.last_seen_at) for r in robots],
            )
            update_rows(
                session,
                robot_table,
                ("id", "running_model_version", "running_model_sha256"),
                [
                    (r.id, r.running_model_version, r.running_model_sha256)
                    for r in robots
                    if r.running_model_changed
                ],
            )
            update_rows(
                session,
                robot_table,
                ("id", "behaviour_state", "behaviour_since", "behaviour_reason"),
                [(r.id, *r.behaviour) for r in robots if r.behaviour],
            )
            update_rows(
                session,
                Video.__table__,
                ("id", "frame_count", "first_frame_ts", "last_frame_ts"),
                [(v.id, v.frame_count, v.first_frame_ts, v.last_frame_ts) for v in videos],
            )
            update_rows(
                session,
                Transport.__table__,
                ("id", "last_frame_at", "last_patient_at"),
                [(t.id, t.last_frame_at, t.last_patient_at) for t in transports],
                keep_stored_if_none=("last_patient_at",),
            )
        for video in videos:
            video.initial_count = video.frame_count
        for robot in robots:
            robot.last_seen_at = None
            if robot.running_model_changed:
                robot.stored_model = (robot.running_model_version, robot.running_model_sha256)
            robot.running_model_changed = robot.fleet_news = False
            robot.behaviour = None
            robot.agent = None
        for transport in transports:
            transport.last_frame_at = None
            transport.last_patient_at = None

    def detach(self) -> IngestContext:
        """After the commit: a context for the next flush that keeps the robot, transport and
        video rows (as plain states, ORM objects converted) and nothing else."""
        transports = {
            key: TransportState(t.id, t.robot_id, t.mode, t.patient, t.location, t.fps)
            if isinstance(t, Transport)
            else t
            for key, t in self.transports.items()
        }
        videos = {
            key: VideoState(
                v.id, v.name, v.frame_count, v.frame_count, v.first_frame_ts, v.last_frame_ts
            )
            if isinstance(v, Video)
            else v
            for key, v in self.videos.items()
        }
        return IngestContext(
            robots=self.robots, transports=transports, videos=videos, pushed_at=self.pushed_at
        )

    def transport(
        self, session: Session, transport_id: str | None
    ) -> TransportState | Transport | None:
        if transport_id is None:
            return None
        if transport_id not in self.transports:
            self.transports[transport_id] = session.get(Transport, transport_id)
        return self.transports[transport_id]

    def flush_rows(self, session: Session) -> int:
        stored = len(self.rows)
        insert_frame_rows(session, self.rows)
        self.rows = []
        self.pending_seqs = {}
        return stored
