"""Robot websocket (/ws/robot): hello, then transports and frame batches, acknowledged only
after the database commit. Bad input closes this connection with a code and a reason; frames
already committed stay, and other robots are unaffected."""

from __future__ import annotations

import asyncio
import json
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool

from backend.alarms.schemas import AlarmOut
from backend.db import transaction
from backend.ingest import service
from backend.models.robots import Robot
from backend.registry import push as model_push
from vigil import protocol
from vigil.protocol import (
    Ack,
    FrameBatch,
    Heartbeat,
    Hello,
    TransportEnd,
    TransportStart,
    Welcome,
)

log = logging.getLogger(__name__)
router = APIRouter()


class CloseConnection(Exception):
    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        # A close frame's reason is limited to 123 bytes.
        self.reason = reason.encode()[:123].decode(errors="ignore")


def _describe(error: ValidationError) -> str:
    first = error.errors()[0]
    where = ".".join(str(part) for part in first["loc"]) or "message"
    return f"invalid {where}: {first['msg']}"


async def _receive_message(websocket: WebSocket) -> protocol.RobotMessage:
    event = await websocket.receive()
    if event["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(event.get("code", 1000))
    text = event.get("text")
    if text is None:
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "binary messages are not accepted")
    if len(text) > protocol.MAX_MESSAGE_BYTES:
        raise CloseConnection(
            protocol.CLOSE_TOO_LARGE, f"message exceeds {protocol.MAX_MESSAGE_BYTES} bytes"
        )
    try:
        return protocol.parse_robot_message(text)
    except ValidationError as error:
        if any(e["type"] == "json_invalid" for e in error.errors()):
            raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "message is not valid JSON") from None
        if any(e["type"] == "union_tag_invalid" for e in error.errors()):
            raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "unknown message type") from None
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, _describe(error)) from None
    except (ValueError, json.JSONDecodeError) as error:
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, str(error)) from None


@router.websocket("/ws/robot")
async def robot_socket(websocket: WebSocket) -> None:
    state = websocket.app.state
    await websocket.accept()
    robot_id: str | None = None
    try:
        try:
            hello = await asyncio.wait_for(
                _receive_message(websocket), state.settings.robot_hello_timeout_s
            )
        except TimeoutError:
            raise CloseConnection(protocol.CLOSE_HELLO_TIMEOUT, "no hello received") from None
        if not isinstance(hello, Hello):
            raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "first message must be hello")
        if hello.protocol != protocol.PROTOCOL_VERSION:
            raise CloseConnection(
                protocol.CLOSE_PROTOCOL_VERSION,
                f"protocol {hello.protocol} not supported (server speaks "
                f"{protocol.PROTOCOL_VERSION})",
            )

        def _authenticate() -> int | None:
            with transaction(state.session_factory) as session:
                return service.authenticate(session, hello).last_seq

        try:
            last_seq = await run_in_threadpool(_authenticate)
        except service.RobotAuthError as error:
            raise CloseConnection(protocol.CLOSE_UNAUTHORIZED, str(error)) from None
        robot_id = hello.robot_id
        state.robots.connect(robot_id, websocket)
        await websocket.send_text(Welcome(robot_id=robot_id, last_seq=last_seq).model_dump_json())
        log.info("robot %s connected (agent %s)", robot_id, hello.agent_version)
        await model_push.on_robot_connected(websocket, robot_id)
        while True:
            message = await _receive_message(websocket)
            await _handle(websocket, robot_id, message)
    except CloseConnection as close:
        log.warning("closing robot %s: %s", robot_id or "?", close.reason)
        await websocket.close(close.code, close.reason)
    except WebSocketDisconnect:
        pass
    finally:
        if robot_id is not None:
            state.robots.disconnect(robot_id, websocket)


async def _handle(websocket: WebSocket, robot_id: str, message: protocol.RobotMessage) -> None:
    state = websocket.app.state
    if isinstance(message, Hello):
        raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, "hello sent twice")

    def _apply():
        with transaction(state.session_factory) as session:
            robot = session.get(Robot, robot_id)
            if robot is None or robot.token_hash is None:
                raise CloseConnection(protocol.CLOSE_UNAUTHORIZED, "robot token revoked")
            if isinstance(message, TransportStart):
                try:
                    service.start_transport(session, robot, message)
                except ValueError as error:
                    raise CloseConnection(protocol.CLOSE_BAD_MESSAGE, str(error)) from None
                return None
            if isinstance(message, TransportEnd):
                service.end_transport(session, robot, message)
                return None
            if isinstance(message, Heartbeat):
                robot.last_seen_at = service.utcnow()
                if message.running_model is not None:
                    robot.running_model_version = message.running_model
                return None
            assert isinstance(message, FrameBatch)
            result = service.store_frames(session, robot, message.frames)
            session.flush()
            alarms = [AlarmOut.model_validate(a).model_dump(mode="json") for a in result.alarms]
            return result, alarms

    outcome = await run_in_threadpool(_apply)  # committed when this returns
    if outcome is None:
        return
    result, alarms = outcome
    state.metrics.frames_ingested.inc(result.stored)
    if result.highest_seq is not None:
        await websocket.send_text(Ack(seq=result.highest_seq).model_dump_json())
    for alarm in alarms:
        await state.hub.publish_alarm(alarm)
