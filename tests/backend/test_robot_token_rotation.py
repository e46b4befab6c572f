"""Rotating a robot's token closes its live connection (4401 and a reason), as revocation does;
over the real websocket of a running backend."""

from __future__ import annotations

import json
from collections.abc import Iterator

import httpx
import pytest
from starlette.websockets import WebSocketDisconnect
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from backend.db import make_engine, make_session_factory, transaction
from backend.models import Robot, Role, User
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN as TEST_ROBOT_TOKEN
from tests.support.live_backend import PASSWORD, ROBOT_ID, ROBOT_TOKEN, LiveServer
from tests.support.passwords import password_hash
from vigil import protocol
from vigil.protocol import Heartbeat, Hello


@pytest.fixture
def server(tmp_path) -> Iterator[LiveServer]:
    live = LiveServer.create(tmp_path)
    engine = make_engine(live.database_url)
    with transaction(make_session_factory(engine)) as session:
        session.add(User(username="ada", password_hash=password_hash(PASSWORD), role=Role.ADMIN))
    engine.dispose()
    live.start()
    yield live
    live.stop()


def connect_robot(server: LiveServer, token: str):
    socket = connect(server.robot_ws_url, open_timeout=10)
    socket.send(Hello(robot_id=ROBOT_ID, token=token).model_dump_json())
    return socket, json.loads(socket.recv(timeout=10))


def close_of(socket) -> tuple[int, str]:
    """Read until the server closes the socket; its close code and reason."""
    with pytest.raises(ConnectionClosed) as closed:
        while True:
            socket.recv(timeout=10)
    assert closed.value.rcvd is not None, "no close frame from the server"
    return closed.value.rcvd.code, closed.value.rcvd.reason


@pytest.mark.parametrize(
    ("method", "reason"), [("POST", "robot token rotated"), ("DELETE", "robot token revoked")]
)
def test_changing_the_token_closes_the_live_robot_socket(server, method, reason):
    socket, welcome = connect_robot(server, ROBOT_TOKEN)
    assert welcome["type"] == "welcome"
    socket.send(Heartbeat(ts=1.0).model_dump_json())  # streaming: the socket is live
    admin = {"Authorization": f"Bearer {server.login('ada')}"}
    response = httpx.request(
        method, f"{server.base_url}/api/robots/{ROBOT_ID}/token", headers=admin, timeout=10
    )
    assert response.status_code == (200 if method == "POST" else 204)
    assert close_of(socket) == (protocol.CLOSE_UNAUTHORIZED, reason)
    # The old token no longer connects; a rotated one does.
    refused = connect(server.robot_ws_url, open_timeout=10)
    refused.send(Hello(robot_id=ROBOT_ID, token=ROBOT_TOKEN).model_dump_json())
    assert close_of(refused)[0] == protocol.CLOSE_UNAUTHORIZED
    if method == "POST":
        fresh, welcome = connect_robot(server, response.json()["token"])
        assert welcome["type"] == "welcome"
        fresh.close()


def test_a_rotation_committed_while_the_robot_connects_still_closes_it(
    client, robot, session_factory
):
    """The rotation commits after the hello's token check but before the connection is
    registered, so the rotation finds no socket to close: the robot socket checks again."""
    registry = client.app.state.services.robots
    register = registry.connect

    def rotate_then_register(robot_id, connection):
        with transaction(session_factory) as session:
            session.get(Robot, robot_id).token_hash = hash_robot_token("the-new-token")
        return register(robot_id, connection)

    registry.connect = rotate_then_register
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=TEST_ROBOT_TOKEN).model_dump_json())
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_text()
    assert (closed.value.code, closed.value.reason) == (
        protocol.CLOSE_UNAUTHORIZED,
        "robot token rotated or revoked",
    )
