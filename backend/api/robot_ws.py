"""Robot websocket (/ws/robot): hello, then transports and frame batches, acknowledged only
after the database commit (by the per-process FrameWriter). Bad input closes this connection
with a code and a reason; frames already committed stay, and other robots are unaffected.

Every message naming a transport (transport_start/end, each frame of a batch,
detection_status) is checked against the transports this robot owns before it reaches the
writer: a transport of another robot closes the connection with CLOSE_FORBIDDEN (4403) and
nothing of that message is stored. The connection remembers the ids it has checked, so a
transport costs one query per connection; the writer checks again inside its transaction."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from sqlalchemy.exc import DataError, SQLAlchemyError
from starlette.concurrency import run_in_threadpool

from backend.ingest import received, service
from backend.realtime.robot_link import MAX_REASON_BYTES, RobotConnection
from backend.services import socket_services
from vigil import protocol
from vigil.protocol import Hello, Welcome

log = logging.getLogger(__name__)
router = APIRouter()


class CloseConnection(Exception):
    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason.encode()[:MAX_REASON_BYTES].decode(errors="ignore")


def describe(error: ValidationError) -> str:
    """The first problem of a message, naming the field: 'invalid frames.0.ts: ...'."""
    first = error.errors()[0]
    loc = list(first["loc"])
    if len(loc) > 1 and isinstance(loc[0], str) and loc[0] in protocol.MESSAGE_TYPES:
        loc = loc[1:]  # the discriminator tag pydantic puts first
    where = ".".join(str(part) for part in loc) or "message"
    return f"invalid {where}: {first['msg']}"


def parse(text: str | None, data: bytes | None) -> protocol.RobotMessage:
    """Validate one raw websocket message or raise CloseConnection with a precise reason."""
    if text is None:
        size = len(data or b"")
        raise CloseConnection(
            protocol.CLOSE_BAD_MESSAGE,
            f"binary message ({size} bytes) not accepted: send JSON text",
        )
    if len(text) > protocol.MAX_MESSAGE_BYTES:
        raise CloseConnection(
            protocol.CLOSE_TOO_LARGE,
            f"message of {len(text)} bytes exceeds {protocol.MAX_MESSAGE_BYTES}",
        )
    try:
        return protocol.parse_robot_message(text)
    except ValidationError as error:
        kinds = {e["type"] for e in error.errors()}
        if "json_invalid" in kinds:
            raise CloseConnection(
                protocol.CLOSE_BAD_MESSAGE, f"message is not valid JSON: {error.errors()[0]['msg']}"
            ) from None
        if "union_tag_invalid" in kinds:
            raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "unknown message type") from None
        if "union_tag_not_found" in kinds or not error.errors()[0]["loc"]:
            raise CloseConnection(
                protocol.CLOSE_BAD_MESSAGE, "message must be a JSON object with a 'type'"
            ) from None
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, describe(error)) from None
    except ValueError as error:
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, str(error)) from None


async def receive_message(websocket: WebSocket) -> protocol.RobotMessage:
    event = await websocket.receive()
    if event["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(event.get("code", 1000))
    return parse(event.get("text"), event.get("bytes"))


async def _hello(websocket: WebSocket) -> Hello:
    state = socket_services(websocket)
    try:
        hello = await asyncio.wait_for(
            receive_message(websocket), state.settings.robot_hello_timeout_s
        )
    except TimeoutError:
        raise CloseConnection(protocol.CLOSE_HELLO_TIMEOUT, "no hello received in time") from None
    if not isinstance(hello, Hello):
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "first message must be hello")
    if hello.protocol != protocol.PROTOCOL_VERSION:
        raise CloseConnection(
            protocol.CLOSE_PROTOCOL_VERSION,
            f"protocol {hello.protocol} not supported (server speaks {protocol.PROTOCOL_VERSION})",
        )
    return hello


def _transport_ids(message: protocol.RobotMessage) -> set[str]:
    if isinstance(message, protocol.FrameBatch):
        return {f.transport_id for f in message.frames if f.transport_id is not None}
    transport_id = getattr(message, "transport_id", None)
    return {transport_id} if transport_id is not None else set()


async def check_transports(
    websocket: WebSocket, connection: RobotConnection, message: protocol.RobotMessage
) -> None:
    """Refuse a message naming another robot's transport (CloseConnection 4403)."""
    unchecked = _transport_ids(message) - connection.checked_transports
    if not unchecked:
        return
    # The writer knows the transports it stored or loaded: a robot reconnecting to its
    # transport costs no query (a thousand of them at once after a replica died).
    writer = socket_services(websocket).writer
    for transport_id in sorted(unchecked):
        owner = writer.transport_owner(transport_id)
        if owner is not None and owner != connection.robot_id:
            raise CloseConnection(
                protocol.CLOSE_FORBIDDEN, str(service.TransportNotOwned(transport_id))
            )
        if owner is not None:
            connection.checked_transports.add(transport_id)
    unchecked -= connection.checked_transports
    if not unchecked:
        return

    def _owners() -> dict[str, str]:
        with socket_services(websocket).session_factory() as session:
            return service.transport_owners(session, unchecked)

    try:
        owners = await run_in_threadpool(_owners)
    except SQLAlchemyError as error:  # storage trouble: the writer's own check still applies
        log.warning(
            "robot %s: transport check deferred to the writer (%s)", connection.robot_id, error
        )
        return
    for transport_id in sorted(unchecked):
        if owners.get(transport_id, connection.robot_id) != connection.robot_id:
            raise CloseConnection(
                protocol.CLOSE_FORBIDDEN, str(service.TransportNotOwned(transport_id))
            )
    connection.checked_transports |= unchecked


@router.websocket("/ws/robot")
async def robot_socket(websocket: WebSocket) -> None:
    state = socket_services(websocket)
    await websocket.accept()
    connection: RobotConnection | None = None
    try:
        hello = await _hello(websocket)

        # Reads only, so the welcome never waits on a stalled write: what the hello says
        # (agent and model versions, inputs, last seen) goes to the frame writer after it.
        def _authenticate() -> tuple[int | None, str, dict[str, str] | None]:
            with state.session_factory() as session:
                robot = service.authenticate(session, hello)
                return robot.last_seq, robot.ward, service.registry_sha256_for(session, hello)

        try:
            last_seq, ward, model_sha256 = await run_in_threadpool(_authenticate)
        except (service.RobotAuthError, DataError):
            raise CloseConnection(
                protocol.CLOSE_UNAUTHORIZED, "unknown robot or wrong or revoked token"
            ) from None
        connection = RobotConnection(websocket, hello.robot_id, ward)
        previous = state.robots.connect(hello.robot_id, connection)
        if previous is not None:
            log.info("robot %s reconnected: closing its older connection", hello.robot_id)
            await previous.close(protocol.CLOSE_REPLACED, "replaced by a newer connection")

        def _token_still_valid() -> bool:
            with state.session_factory() as session:
                return service.token_still_valid(session, hello)

        # A rotation or revocation committed between the check above and `connect` found no
        # connection to close: checked again now that this one is registered (one committed
        # later finds it and closes it).
        if not await run_in_threadpool(_token_still_valid):
            raise CloseConnection(protocol.CLOSE_UNAUTHORIZED, "robot token rotated or revoked")
        await connection.send(
            Welcome(robot_id=hello.robot_id, last_seq=last_seq, model_sha256=model_sha256)
        )
        log.info("robot %s connected (agent %s)", hello.robot_id, hello.agent_version)
        writer = state.writer
        await writer.submit(connection, hello, time.perf_counter())
        await state.assignments.on_robot_connected(
            hello.robot_id, (hello.running_model, hello.running_sha256)
        )
        while True:
            message = await receive_message(websocket)
            received_at = time.perf_counter()
            if isinstance(message, Hello):
                raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "hello sent twice")
            await check_transports(websocket, connection, message)
            if isinstance(message, protocol.FrameBatch):
                message = received.from_batch(message)
            elif isinstance(message, protocol.Heartbeat) and message.running_model is not None:
                state.assignments.robot_reported(
                    hello.robot_id, message.running_model, message.running_sha256
                )
            await writer.submit(connection, message, received_at)
    except CloseConnection as close:
        log.warning("closing robot connection: %s (%s)", close.reason, close.code)
        if connection is not None:
            await connection.close(close.code, close.reason)
        else:
            with contextlib.suppress(Exception):
                await websocket.close(close.code, close.reason)
    except (WebSocketDisconnect, RuntimeError):
        pass  # RuntimeError: the socket was closed under us (replaced or rejected)
    finally:
        if connection is not None:
            connection.closed = True
            state.robots.disconnect(connection.robot_id, connection)
            if state.robots.socket(connection.robot_id) is None:  # not replaced: offline now
                try:
                    await state.effects.publish_fleet([connection.robot_id])
                except Exception:
                    log.exception("fleet change of %s not published", connection.robot_id)
