"""Browser websocket: first a snapshot of every unresolved alarm, then each change.

Authentication never travels in the URL (uvicorn's access log records URLs): the first message
is `{"type": "auth", "token": "..."}` (the tab's session token; without "token" the session
cookie is used), or a non-browser client sends `Authorization: Bearer ...` with the handshake.
A refused session is accepted and then closed with 4401 and a reason, so the browser sees the
code (a refusal before accepting reaches it as 1006) and returns to the login page."""

from __future__ import annotations

import asyncio
import json

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool

from backend.alarms import queries
from backend.alarms.schemas import AlarmOut
from backend.deps import SESSION_COOKIE, session_from_token
from backend.realtime.hub import ALARM_VIEWERS, BrowserConnection
from backend.services import Services, socket_services

router = APIRouter()

CLOSE_BAD_MESSAGE = 4400
CLOSE_UNAUTHORIZED = 4401
CLOSE_FORBIDDEN = 4403
CLOSE_AUTH_TIMEOUT = 4408


def _origin_allowed(websocket: WebSocket, trusted: list[str]) -> bool:
    """Browsers always send Origin with a websocket handshake: it must be this site (or a
    trusted origin), else another site's page could open the socket with the user's cookie."""
    origin = websocket.headers.get("origin")
    if origin is None or origin in trusted:
        return True
    scheme, _, rest = origin.partition("://")
    return scheme in ("http", "https") and rest == websocket.headers.get("host")


def _header_token(websocket: WebSocket) -> str | None:
    scheme, _, value = websocket.headers.get("authorization", "").partition(" ")
    return value if scheme.lower() == "bearer" and value else None


async def _first_message_token(websocket: WebSocket, timeout_s: float) -> str | None | int:
    """The token from the auth message (the cookie's when it names none), or a close code."""
    try:
        message = await asyncio.wait_for(websocket.receive(), timeout_s)
    except TimeoutError:
        return CLOSE_AUTH_TIMEOUT
    if message["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(message.get("code", 1000))
    try:
        body = json.loads(message.get("text") or "")
    except ValueError:
        body = None
    if not isinstance(body, dict) or body.get("type") != "auth":
        return CLOSE_BAD_MESSAGE
    token = body.get("token")
    if token is None:
        return websocket.cookies.get(SESSION_COOKIE)
    return token if isinstance(token, str) else CLOSE_BAD_MESSAGE


def _signed_in_user(state: Services, token: str):
    """(user, claims) of a valid session, else None; the user stays readable after the
    session closes (its ward and role scope the snapshot)."""
    with state.session_factory() as session:
        found = session_from_token(session, state.settings, token)
        if found is not None:
            session.expunge(found[0])
        return found


_ALARMS = TypeAdapter(list[AlarmOut])


def _snapshot(state: Services, user) -> list[dict]:
    """Every unresolved alarm the user may see, as the board's JSON (one query, validated and
    dumped as one list)."""
    with state.session_factory() as session:
        rows = queries.unresolved_rows(session, user)
    return _ALARMS.dump_python(_ALARMS.validate_python(rows), mode="json")


def _session_still_valid(state: Services, token: str) -> bool:
    with state.session_factory() as session:
        return session_from_token(session, state.settings, token) is not None


@router.websocket("/ws/browser")
async def browser_socket(websocket: WebSocket) -> None:
    state = socket_services(websocket)
    await websocket.accept()
    if not _origin_allowed(websocket, state.settings.trusted_origins):
        await websocket.close(CLOSE_FORBIDDEN, "socket opened from another site")
        return
    if "token" in websocket.query_params:
        await websocket.close(
            CLOSE_UNAUTHORIZED,
            "token in the URL refused (access logs record URLs): send it in the first message",
        )
        return
    token = _header_token(websocket)
    if token is None:
        try:
            token = await _first_message_token(websocket, state.settings.browser_auth_timeout_s)
        except WebSocketDisconnect:
            return
        if token == CLOSE_AUTH_TIMEOUT:
            await websocket.close(CLOSE_AUTH_TIMEOUT, "no auth message in time")
            return
        if token == CLOSE_BAD_MESSAGE:
            await websocket.close(
                CLOSE_BAD_MESSAGE, 'the first message must be {"type": "auth", "token": "..."}'
            )
            return
    # Database work runs off the event loop, so other boards' pushes do not wait for it.
    found = await run_in_threadpool(_signed_in_user, state, token)
    if found is None:
        await websocket.close(CLOSE_UNAUTHORIZED, "not signed in or session expired")
        return
    user, claims = found
    if user.role not in ALARM_VIEWERS:
        await websocket.close(CLOSE_FORBIDDEN, f"role {user.role} receives no alarms")
        return
    connection = BrowserConnection(websocket, user.id, user.role, user.ward, claims.jti)
    # Register before reading the snapshot so no alarm committed in between is missed.
    state.hub.add(connection)
    try:
        alarms = await run_in_threadpool(_snapshot, state, user)
    except BaseException:
        state.hub.remove(connection)
        raise
    # Fail open: alarms pushed before they could be stored (storage stalled) are on the board too.
    alarms += [a for a in state.writer.unstored_alarms() if connection.can_see(a["ward"])]
    try:
        await state.hub.send(connection, {"type": "snapshot", "alarms": alarms})
        while True:
            event = await websocket.receive()
            if event["type"] == "websocket.disconnect":
                break
            if event.get("text") is None:
                # A binary frame: close with a code and a reason, never drop the connection.
                size = len(event.get("bytes") or b"")
                await websocket.close(
                    CLOSE_BAD_MESSAGE, f"binary message ({size} bytes) not accepted: send text"
                )
                break
            if event["text"] == "ping":
                # Each ping (every 10 s from the page) re-checks the session, off the event
                # loop: a logout, deactivation or expiry seen by another replica (or by none:
                # the token simply ran out) closes this socket too, within one ping.
                if not await run_in_threadpool(_session_still_valid, state, token):
                    state.hub.remove(connection)
                    await websocket.close(CLOSE_UNAUTHORIZED, "session ended")
                    return
                await state.hub.send(connection, {"type": "pong"})
    except WebSocketDisconnect:
        pass
    finally:
        state.hub.remove(connection)
