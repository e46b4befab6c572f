"""Robot <-> backend wire protocol (JSON text messages over a websocket), version 1.

Robot -> server: ``hello`` (first message), ``transport_start``, ``frames``, ``transport_end``,
``heartbeat``, ``detection_status``, ``emergency_reset``, ``behaviour_changed``.  Server ->
robot: ``welcome``, ``ack`` (highest sequence number committed to the database, never sent
before the commit), ``assign_model``, ``error``, ``alarm_acknowledged``, ``alarm_resolved``.

A message that does not validate closes the connection with one of the CLOSE_* codes and a
reason naming the bad field; frames stored before it are unaffected. Messages are parsed
strictly: a number sent as a string ("seq": "12") is refused, not converted.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    TypeAdapter,
    model_serializer,
    model_validator,
)

from vigil.classes import BehaviourState, Decision, TransportMode
from vigil.inputs import InputName
from vigil.skeleton import N_FLOOR, N_KEYPOINTS

PROTOCOL_VERSION = 1
MAX_MESSAGE_BYTES = 1_000_000
MAX_FRAMES_PER_BATCH = 500

# Websocket close codes (application range 4000-4999).
CLOSE_BAD_MESSAGE = 4400  # not JSON, unknown type, missing or invalid field
CLOSE_UNAUTHORIZED = 4401  # wrong or revoked robot token
CLOSE_FORBIDDEN = 4403  # a message names a transport that belongs to another robot
CLOSE_PROTOCOL_VERSION = 4406  # protocol version the server does not speak
CLOSE_HELLO_TIMEOUT = 4408  # no hello in time
CLOSE_TOO_LARGE = 4413  # message larger than MAX_MESSAGE_BYTES
CLOSE_REPLACED = 4409  # the same robot connected again; the older connection is closed
CLOSE_INTERNAL_ERROR = 1011  # the server could not store the message; reconnect and resend


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
Sha256 = Annotated[str, Field(pattern=r"^[0-9a-f]{64}$")]
#: 9999-12-31T23:59:59Z, the last instant a datetime holds: a transport's start or end time
#: beyond it (or before 1970) is the robot's error, refused with CLOSE_BAD_MESSAGE.
MAX_UNIX_TIME = 253_402_300_799.0
UnixTime = Annotated[float, Field(ge=0, le=MAX_UNIX_TIME, allow_inf_nan=False)]
Point = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]


class _Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Hello(_Message):
    type: Literal["hello"] = "hello"
    protocol: int = PROTOCOL_VERSION
    robot_id: str = Field(min_length=1, max_length=64)
    token: str = Field(min_length=1, max_length=256)
    agent_version: str = Field(default="unknown", max_length=64)
    running_model: str | None = Field(default=None, max_length=64)
    # Protocol 1 extension: the inputs this robot can feed a model (vigil.inputs); older
    # agents omit it and are taken to feed keypoints only.
    inputs: list[InputName] | None = Field(
        default=None, description="inputs the robot can feed a model: keypoints, depth, floor"
    )
    # Protocol 1 extension: the sha256 of the model files the robot actually runs (computed
    # from the bytes it loaded), and its keypoints-only fallback. The welcome answers with the
    # registry's sha256 of those versions; the fleet compares the running one with its target.
    running_sha256: Sha256 | None = Field(
        default=None, description="sha256 of the model file running_model was loaded from"
    )
    fallback_model: str | None = Field(default=None, max_length=64)
    fallback_sha256: Sha256 | None = None


class TransportStart(_Message):
    type: Literal["transport_start"] = "transport_start"
    transport_id: str = Field(min_length=1, max_length=64)
    mode: TransportMode
    patient: str | None = Field(default=None, max_length=64, description="patient pseudonym")
    location: str | None = Field(default=None, max_length=128)
    ts: UnixTime
    # Protocol 1 extension: the source's real frame rate (a 23.976 fps clip is not 30 fps).
    fps: float | None = Field(default=None, gt=0, le=1000, allow_inf_nan=False)


class TransportEnd(_Message):
    type: Literal["transport_end"] = "transport_end"
    transport_id: str = Field(min_length=1, max_length=64)
    ts: UnixTime


class ShadowDecision(_Message):
    decision: Decision
    scores: dict[Decision, FiniteFloat] = Field(default_factory=dict)
    model_version: str = Field(max_length=64)


class FrameRecord(_Message):
    """One classified frame. keypoints: 25 x [x, y, confidence]; depth: 25 metres or null;
    floor: the 3 floor measures or null.

    Lengths and finiteness are checked by pydantic-core constraints (not Python validators):
    this is the ingest hot path.
    """

    seq: int = Field(ge=0)
    ts: FiniteFloat
    transport_id: str | None = Field(default=None, max_length=64)
    keypoints: list[Point] = Field(min_length=N_KEYPOINTS, max_length=N_KEYPOINTS)
    # JSON has no NaN: unknown depth travels as null.
    depth: list[FiniteFloat | None] | None = Field(
        default=None, min_length=N_KEYPOINTS, max_length=N_KEYPOINTS
    )
    # Floor measures (vigil.skeleton.FLOOR_FIELDS); absent when the robot has no camera mount.
    floor: list[FiniteFloat | None] | None = Field(
        default=None, min_length=N_FLOOR, max_length=N_FLOOR
    )
    decision: Decision | None = None
    scores: dict[Decision, FiniteFloat] = Field(default_factory=dict)
    model_version: str | None = Field(default=None, max_length=64)
    threshold: FiniteFloat | None = None
    delay_ms: int | None = Field(default=None, ge=0)
    shadow: ShadowDecision | None = Field(
        default=None, description="a candidate model's decision, stored but never alarmed"
    )


class FrameBatch(_Message):
    type: Literal["frames"] = "frames"
    frames: list[FrameRecord] = Field(min_length=1, max_length=MAX_FRAMES_PER_BATCH)


class Heartbeat(_Message):
    type: Literal["heartbeat"] = "heartbeat"
    ts: FiniteFloat
    running_model: str | None = None
    # Optional robot health (protocol 1 extension; older robots omit them).
    outbox_frames: int | None = Field(default=None, ge=0, description="frames not yet acked")
    dropped_frames: int | None = Field(
        default=None, ge=0, description="frames the robot's outbox dropped under its disk budget"
    )
    model_error: str | None = Field(
        default=None, max_length=500, description="why the robot refused its assigned model"
    )
    running_sha256: Sha256 | None = Field(
        default=None, description="sha256 of the file running_model was loaded from"
    )


class DetectionStatus(_Message):
    """Sent when the robot's detection degrades or recovers (protocol 1 extension).

    degraded: the assigned model lacks an input it needs (``missing_inputs``: the depth stream
    stopped, no camera mount...) and the robot classifies with ``running_model``, its
    keypoints-only fallback (None: it has none and keeps the assigned model on what it has).
    The backend raises a technical alarm "detection degraded" while degraded and clears it on
    the next status with degraded false. Queued in the outbox like frames: it is never lost.
    """

    type: Literal["detection_status"] = "detection_status"
    ts: FiniteFloat
    transport_id: str | None = Field(default=None, max_length=64)
    degraded: bool
    missing_inputs: list[InputName] = Field(default_factory=list)
    assigned_model: str | None = Field(default=None, max_length=64)
    running_model: str | None = Field(default=None, max_length=64)
    reason: str = Field(default="", max_length=500)


class EmergencyReset(_Message):
    """The robot's emergency stop was reset on the robot itself (`vigil-robot reset`, its local
    socket), not by a nurse's resolve (protocol 1 extension). Queued in the outbox, so a reset
    made while the backend was unreachable is told on reconnect; the backend writes it into the
    audit of the robot's alarm (``alarm_id``, else the transport's unresolved Emergency)."""

    type: Literal["emergency_reset"] = "emergency_reset"
    ts: FiniteFloat
    transport_id: str | None = Field(default=None, max_length=64)
    alarm_id: int | None = Field(default=None, ge=1)
    by: str = Field(default="local", max_length=64, description="who reset: cli, local socket")


class BehaviourChanged(_Message):
    """The robot's behaviour changed (robot_agent.behaviour: transporting, paused, emergency
    stop, detection degraded), protocol 1 extension. Queued in the outbox like frames, in stream
    order after the frames that caused it; the backend keeps each robot's last state for the
    fleet page and writes it into the audit of the transport's alarm (the board shows it)."""

    type: Literal["behaviour_changed"] = "behaviour_changed"
    ts: FiniteFloat
    state: BehaviourState
    reason: str = Field(default="", max_length=500)
    since: UnixTime
    transport_id: str | None = Field(default=None, max_length=64)
    alarm_id: int | None = Field(default=None, ge=1)


RobotMessage = Annotated[
    Hello
    | TransportStart
    | TransportEnd
    | FrameBatch
    | Heartbeat
    | DetectionStatus
    | EmergencyReset
    | BehaviourChanged,
    Field(discriminator="type"),
]
robot_message_adapter: TypeAdapter[RobotMessage] = TypeAdapter(RobotMessage)
MESSAGE_TYPES = frozenset(
    {
        "hello",
        "transport_start",
        "transport_end",
        "frames",
        "heartbeat",
        "detection_status",
        "emergency_reset",
        "behaviour_changed",
    }
)


class ModelAssignment(_Message):
    type: Literal["assign_model"] = "assign_model"
    version: str
    url: str
    sha256: str
    manifest: dict
    shadow: bool = False
    # Protocol 1 extension: with shadow=False, also stop the shadow model the robot runs (its
    # shadow deployment was withdrawn). Sent only when true, so robots that predate it (and
    # refuse unknown fields) still read every other assignment.
    stop_shadow: bool = Field(
        default=False, description="also stop the shadow model (only with shadow=false)"
    )
    # Protocol 1 extension: a keypoints-only model the robot keeps beside its assigned one and
    # switches to when the assigned model lacks an input (vigil.inputs). Sent only when true.
    fallback: bool = Field(
        default=False, description="the keypoints-only fallback, kept beside the assigned model"
    )

    @model_validator(mode="after")
    def _stop_shadow_with_production_only(self) -> ModelAssignment:
        if self.stop_shadow and self.shadow:
            raise ValueError("stop_shadow: only allowed with shadow=false")
        if self.fallback and (self.shadow or self.stop_shadow):
            raise ValueError("fallback: not together with shadow or stop_shadow")
        return self

    @model_serializer(mode="wrap")
    def _omit_extensions_unless_set(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        for extension in ("stop_shadow", "fallback"):
            if not getattr(self, extension):
                data.pop(extension, None)
        return data


class Welcome(_Message):
    type: Literal["welcome"] = "welcome"
    protocol: int = PROTOCOL_VERSION
    robot_id: str
    last_seq: int | None = Field(description="highest sequence number already committed")
    # Protocol 1 extension, sent only to a robot whose hello gave a sha256: the registry's
    # sha256 of each version the hello named (running_model, fallback_model) that the registry
    # knows. The robot refuses a model whose file does not match (never runs it).
    model_sha256: dict[str, Sha256] | None = Field(
        default=None, description="registry sha256 of the versions the hello named"
    )

    @model_serializer(mode="wrap")
    def _omit_extensions_unless_set(self, handler: SerializerFunctionWrapHandler) -> dict:
        data = handler(self)
        if self.model_sha256 is None:
            data.pop("model_sha256", None)
        return data


class Ack(_Message):
    type: Literal["ack"] = "ack"
    seq: int


class ServerError(_Message):
    type: Literal["error"] = "error"
    message: str


class AlarmAcknowledged(_Message):
    """A nurse acknowledged this robot's alarm: help is coming (protocol 1 extension). The robot
    shows it locally (log, local socket, hook); its behaviour does not change."""

    type: Literal["alarm_acknowledged"] = "alarm_acknowledged"
    alarm_id: int = Field(ge=1)
    kind: str = Field(max_length=32)
    transport_id: str | None = Field(default=None, max_length=64)
    by: str = Field(max_length=128, description="who acknowledged (role:username)")
    at: FiniteFloat = Field(description="when (Unix time)")


class AlarmResolved(_Message):
    """A nurse resolved this robot's alarm (protocol 1 extension): an emergency stop is
    released and the robot goes on transporting."""

    type: Literal["alarm_resolved"] = "alarm_resolved"
    alarm_id: int = Field(ge=1)
    kind: str = Field(max_length=32)
    transport_id: str | None = Field(default=None, max_length=64)
    by: str = Field(max_length=128, description="who resolved (role:username)")
    at: FiniteFloat = Field(description="when (Unix time)")
    verdict: str | None = Field(default=None, max_length=32)


def alarm_acknowledged(
    alarm_id: int, kind: str, transport_id: str | None, by: str, at: float
) -> AlarmAcknowledged:
    return AlarmAcknowledged(alarm_id=alarm_id, kind=kind, transport_id=transport_id, by=by, at=at)


def alarm_resolved(
    alarm_id: int,
    kind: str,
    transport_id: str | None,
    by: str,
    at: float,
    verdict: str | None = None,
) -> AlarmResolved:
    return AlarmResolved(
        alarm_id=alarm_id, kind=kind, transport_id=transport_id, by=by, at=at, verdict=verdict
    )


def ack_json(seq: int) -> str:
    """`Ack(seq=seq)` as JSON, for the hot path (one per committed batch of every robot):
    the same text `Ack.model_dump_json()` gives (tests/vigil/test_protocol_builders.py compares
    them), without building and validating a model each time."""
    return f'{{"type":"ack","seq":{int(seq)}}}'


# --- the robot's frames on the wire -------------------------------------------------------------
# A frame is serialised once, when it is classified, without its sequence number: the robot's
# outbox stores that body and numbers it (frame_json) when it is sent, again after a
# reconnect or a renumbering, and frames travel in batches (frame_batch_json). The three texts
# are the models' own JSON (tests/vigil/test_protocol_builders.py compares them), without
# building a FrameBatch of FrameRecords for every batch sent.

_WITHOUT_SEQ = frozenset({"seq"})
_FRAMES_OPEN = '{"type":"frames","frames":['


def frame_body_json(frame: FrameRecord) -> str:
    """`frame` as JSON without its "seq" (the outbox gives the number) and without the fields
    that are None (their default): `frame.model_dump_json(exclude={"seq"}, exclude_none=True)`.
    Always an object with at least "ts" and "keypoints"."""
    return frame.model_dump_json(exclude=_WITHOUT_SEQ, exclude_none=True)


def frame_json(seq: int, body: str) -> str:
    """The frame `body` (frame_body_json: a JSON object without "seq") numbered `seq`: the
    FrameRecord's JSON, "seq" first, as `FrameRecord.model_dump_json(exclude_none=True)`
    writes it. The body is not parsed again (the hot path); it must be a non-empty object."""
    if not body.startswith('{"'):
        raise ValueError(f"a frame body is a non-empty JSON object, got {body[:40]!r}")
    return f'{{"seq":{int(seq)},{body[1:]}'


def frame_batch_json(frames: Sequence[str]) -> str:
    """A `frames` message of frames already as FrameRecord JSON (frame_json), in order: the
    same text as `FrameBatch(frames=...).model_dump_json(exclude_none=True)`. 1 to
    MAX_FRAMES_PER_BATCH frames, as the backend accepts."""
    if not 1 <= len(frames) <= MAX_FRAMES_PER_BATCH:
        raise ValueError(
            f"a frame batch holds 1 to {MAX_FRAMES_PER_BATCH} frames, got {len(frames)}"
        )
    return _FRAMES_OPEN + ",".join(frames) + "]}"


ServerMessage = Annotated[
    Welcome | Ack | ModelAssignment | ServerError | AlarmAcknowledged | AlarmResolved,
    Field(discriminator="type"),
]
server_message_adapter: TypeAdapter[ServerMessage] = TypeAdapter(ServerMessage)


def parse_robot_message(raw: str | bytes) -> RobotMessage:
    """Parse and validate one robot message; raises pydantic.ValidationError or ValueError.

    Strict: JSON types must match (an integer field refuses "12", a flag refuses "true");
    enums still read their string values and a float field takes an integer."""
    return robot_message_adapter.validate_json(raw, strict=True)
