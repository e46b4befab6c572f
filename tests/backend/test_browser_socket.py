"""Browser websocket input: the browser sends only the text "ping"; anything else it cannot
mean is answered with a close code and a reason, never by dropping the connection."""

from __future__ import annotations

import pytest
from starlette.websockets import WebSocketDisconnect

from backend.api.browser_ws import CLOSE_BAD_MESSAGE
from backend.models import Role


def connect(client, token: str):
    return client.websocket_connect("/ws/browser", headers={"Authorization": f"Bearer {token}"})


def test_ping_is_answered(client, make_account):
    nurse = make_account(Role.NURSE, ward="ward-a")
    with connect(client, nurse.token) as browser:
        assert browser.receive_json()["type"] == "snapshot"
        browser.send_text("ping")
        assert browser.receive_json() == {"type": "pong"}


def test_binary_frame_is_closed_with_4400_and_a_reason(client, make_account):
    nurse = make_account(Role.NURSE, ward="ward-a")
    with connect(client, nurse.token) as browser:
        assert browser.receive_json()["type"] == "snapshot"
        browser.send_bytes(b"\x00\xff binary")
        with pytest.raises(WebSocketDisconnect) as closed:
            browser.receive_text()
    assert closed.value.code == CLOSE_BAD_MESSAGE == 4400
    assert "binary message (9 bytes) not accepted" in closed.value.reason
