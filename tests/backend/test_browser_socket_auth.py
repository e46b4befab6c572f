"""The browser socket authenticates without the token in its URL (uvicorn logs URLs): a first
`auth` message (the tab's token, or the cookie) or a bearer header. Refusals are sent after
accepting, so the browser sees 4401/4403 with a reason instead of 1006."""

from __future__ import annotations

import pytest
from starlette.websockets import WebSocketDisconnect

from backend.deps import SESSION_COOKIE
from backend.models import Role


@pytest.fixture
def settings(settings):
    settings.browser_auth_timeout_s = 0.3
    return settings


def closed_with(ws) -> tuple[int, str]:
    with pytest.raises(WebSocketDisconnect) as closed:
        ws.receive_json()
    return closed.value.code, closed.value.reason


def test_the_first_message_carries_the_token(client, make_account):
    nurse = make_account(Role.NURSE)
    with client.websocket_connect("/ws/browser") as ws:
        ws.send_json({"type": "auth", "token": nurse.token})
        assert ws.receive_json()["type"] == "snapshot"
        ws.send_text("ping")
        assert ws.receive_json() == {"type": "pong"}


def test_an_auth_message_without_token_uses_the_session_cookie(client, make_account):
    nurse = make_account(Role.NURSE)
    client.cookies.set(SESSION_COOKIE, nurse.token)
    with client.websocket_connect("/ws/browser") as ws:
        ws.send_json({"type": "auth"})
        assert ws.receive_json()["type"] == "snapshot"


def test_a_token_in_the_url_is_refused_with_a_reason(client, make_account):
    nurse = make_account(Role.NURSE)
    with client.websocket_connect(f"/ws/browser?token={nurse.token}") as ws:
        code, reason = closed_with(ws)
    assert code == 4401 and "URL" in reason


def test_an_expired_or_garbage_session_is_accepted_then_closed_4401(client):
    # Entering the block means the handshake was accepted (before: refused, seen as 1006).
    with client.websocket_connect("/ws/browser") as ws:
        ws.send_json({"type": "auth", "token": "not.a-token"})
        assert closed_with(ws) == (4401, "not signed in or session expired")


def test_a_socket_opened_from_another_site_is_closed_4403(client, make_account):
    nurse = make_account(Role.NURSE)
    headers = {**nurse.headers, "Origin": "https://evil.example"}
    with client.websocket_connect("/ws/browser", headers=headers) as ws:
        code, reason = closed_with(ws)
    assert code == 4403 and "another site" in reason
    same_site = {**nurse.headers, "Origin": "http://testserver"}
    with client.websocket_connect("/ws/browser", headers=same_site) as ws:
        assert ws.receive_json()["type"] == "snapshot"


def test_no_auth_message_in_time_or_a_wrong_one_closes_the_socket(client):
    with client.websocket_connect("/ws/browser") as ws:
        assert closed_with(ws)[0] == 4408
    with client.websocket_connect("/ws/browser") as ws:
        ws.send_text("ping")
        assert closed_with(ws)[0] == 4400


def test_a_session_ended_elsewhere_closes_the_socket_at_the_next_ping(
    client, make_account, session_factory
):
    from sqlalchemy import update

    from backend.db import transaction
    from backend.models import User

    nurse = make_account(Role.NURSE)
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as ws:
        assert ws.receive_json()["type"] == "snapshot"
        ws.send_text("ping")
        assert ws.receive_json() == {"type": "pong"}
        # Deactivated by another replica (or straight in the database): this one's hub
        # never heard of it.
        with transaction(session_factory) as session:
            session.execute(
                update(User).where(User.username == nurse.username).values(active=False)
            )
        ws.send_text("ping")
        assert closed_with(ws) == (4401, "session ended")
