"""Browser websocket: first a snapshot of every unresolved alarm, then each change."""

from __future__ import annotations

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from backend.alarms import queries
from backend.alarms.schemas import AlarmOut
from backend.deps import SESSION_COOKIE, user_from_token
from backend.realtime.hub import ALARM_VIEWERS, BrowserConnection

router = APIRouter()

CLOSE_UNAUTHORIZED = 4401
CLOSE_FORBIDDEN = 4403
CLOSE_BAD_MESSAGE = 4400  # the browser sends only the text "ping"


@router.websocket("/ws/browser")
async def browser_socket(websocket: WebSocket) -> None:
    state = websocket.app.state
    token = websocket.query_params.get("token") or websocket.cookies.get(SESSION_COOKIE)
    with state.session_factory() as session:
        user = user_from_token(session, state.settings, token)
        if user is None:
            await websocket.close(CLOSE_UNAUTHORIZED, "not signed in or session expired")
            return
        if user.role not in ALARM_VIEWERS:
            await websocket.close(CLOSE_FORBIDDEN, f"role {user.role} receives no alarms")
            return
        await websocket.accept()
        connection = BrowserConnection(websocket, user.id, user.role, user.ward)
        # Register before reading the snapshot so no alarm committed in between is missed.
        state.hub.add(connection)
        alarms = [
            AlarmOut.model_validate(a).model_dump(mode="json")
            for a in queries.unresolved_for(session, user)
        ]
    # Fail open: alarms pushed before they could be stored (storage stalled) are on the board too.
    writer = getattr(state, "writer", None)
    if writer is not None:
        alarms += [a for a in writer.unstored_alarms() if connection.can_see(a["ward"])]
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
                await state.hub.send(connection, {"type": "pong"})
    except WebSocketDisconnect:
        pass
    finally:
        state.hub.remove(connection)
