"""Logout revokes the session on the server; an admin deactivates and reactivates users, and a
deactivated user's sessions stop at once, open browser sockets included."""

from __future__ import annotations

import pytest
from starlette.websockets import WebSocketDisconnect

from backend.models import Role
from tests.backend.conftest import PASSWORD


def login(client, username: str, password: str = PASSWORD):
    response = client.post("/api/auth/login", json={"username": username, "password": password})
    client.cookies.clear()
    return response


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def test_logout_revokes_that_session_only(client, make_account):
    nurse = make_account(Role.NURSE)
    other = login(client, nurse.username).json()["access_token"]
    assert client.get("/api/auth/me", headers=nurse.headers).status_code == 200

    assert client.post("/api/auth/logout", headers=nurse.headers).status_code == 204
    # Before the fix the token stayed valid for 12 h after logout.
    assert client.get("/api/auth/me", headers=nurse.headers).status_code == 401
    assert client.post("/api/auth/logout", headers=nurse.headers).status_code == 401
    assert client.get("/api/auth/me", headers=bearer(other)).status_code == 200


def test_logout_closes_the_browser_socket_opened_with_that_session(client, make_account):
    nurse = make_account(Role.NURSE)
    with client.websocket_connect("/ws/browser", headers=nurse.headers) as ws:
        assert ws.receive_json()["type"] == "snapshot"
        assert client.post("/api/auth/logout", headers=nurse.headers).status_code == 204
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
    assert closed.value.code == 4401
    assert closed.value.reason == "signed out"


def test_deactivation_stops_every_session_at_once_and_reactivation_allows_sign_in(
    client, make_account
):
    admin = make_account(Role.ADMIN, ward=None)
    nurse = make_account(Role.NURSE)
    second = login(client, nurse.username).json()["access_token"]
    users = {u["username"]: u for u in client.get("/api/users", headers=admin.headers).json()}
    nurse_id = users[nurse.username]["id"]
    assert users[nurse.username]["active"] is True

    with client.websocket_connect("/ws/browser", headers=nurse.headers) as ws:
        assert ws.receive_json()["type"] == "snapshot"
        response = client.post(f"/api/users/{nurse_id}/deactivate", headers=admin.headers)
        assert response.status_code == 200 and response.json()["active"] is False
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
    assert (closed.value.code, closed.value.reason) == (4401, "account deactivated")
    for token in (nurse.token, second):
        assert client.get("/api/auth/me", headers=bearer(token)).status_code == 401
    assert login(client, nurse.username).status_code == 401

    response = client.post(f"/api/users/{nurse_id}/reactivate", headers=admin.headers)
    assert response.status_code == 200 and response.json()["active"] is True
    assert login(client, nurse.username).status_code == 200


def test_deactivation_refusals(client, make_account):
    admin = make_account(Role.ADMIN, ward=None)
    engineer = make_account(Role.ENGINEER, ward=None)
    admin_id = client.get("/api/auth/me", headers=admin.headers).json()["id"]
    response = client.post(f"/api/users/{admin_id}/deactivate", headers=admin.headers)
    assert response.status_code == 409 and "your own account" in response.json()["detail"]
    assert client.post("/api/users/999999/deactivate", headers=admin.headers).status_code == 404
    refused = client.post(f"/api/users/{admin_id}/deactivate", headers=engineer.headers)
    assert refused.status_code == 403
    assert client.get("/api/auth/me", headers=admin.headers).status_code == 200
