"""Walk every route of the OpenAPI with every role, anonymously and with a robot token, and
check each answer against the one permission table (backend/permissions.py)."""

from __future__ import annotations

import re

import pytest

from backend.models import Role
from backend.permissions import PERMISSIONS, PUBLIC
from tests.backend.conftest import ROBOT_TOKEN

HTTP_METHODS = {"get", "post", "put", "patch", "delete"}
PATH_VALUES = {"robot_id": "robot-a", "alarm_id": "1", "video_id": "1", "transport_id": "t-1"}


def openapi_routes(app) -> list[tuple[str, str, dict]]:
    routes = []
    for path, item in app.openapi()["paths"].items():
        for method, operation in item.items():
            if method in HTTP_METHODS:
                routes.append((method.upper(), path, operation))
    return routes


def concrete(path: str) -> str:
    return re.sub(r"\{(\w+)\}", lambda m: PATH_VALUES.get(m.group(1), "1"), path)


def minimal_body(app, operation: dict) -> dict | None:
    """A JSON object for routes with a body (its content does not matter for the auth check,
    which runs before validation; it only has to be JSON)."""
    return {} if "requestBody" in operation else None


def test_every_route_is_in_the_permission_table_and_nothing_else(client):
    routes = {(method, path) for method, path, _ in openapi_routes(client.app)}
    assert routes, "the OpenAPI lists no routes"
    assert routes - PERMISSIONS.keys() == set(), "routes without a permission entry"
    assert PERMISSIONS.keys() - routes == set(), "permission entries for routes that do not exist"


def test_every_route_answers_every_caller_as_the_table_says(client, make_account, robot):
    accounts = {role: make_account(role, ward="ward-a") for role in Role}
    callers: list[tuple[str, dict[str, str], Role | None]] = [
        ("anonymous", {}, None),
        ("robot token", {"Authorization": f"Bearer {ROBOT_TOKEN}"}, None),
        ("garbage token", {"Authorization": "Bearer not.a-token"}, None),
        *((role.value, accounts[role].headers, role) for role in Role),
    ]
    failures = []
    for method, path, operation in sorted(openapi_routes(client.app), key=_destructive_last):
        allowed_roles = PERMISSIONS[(method, path)]
        for name, headers, role in callers:
            client.cookies.clear()
            response = client.request(
                method, concrete(path), headers=headers, json=minimal_body(client.app, operation)
            )
            if allowed_roles == PUBLIC:
                allowed = True
            else:
                allowed = role is not None and role in allowed_roles
            denied = response.status_code in (401, 403)
            if allowed == denied:
                failures.append(
                    f"{method} {path} as {name}: {response.status_code} "
                    f"(expected {'allowed' if allowed else 'denied'})"
                )
    assert not failures, "\n".join(failures)


def _destructive_last(route: tuple[str, str, dict]) -> tuple[int, str, str]:
    """Token revocation and (de/re)activation run late, logout (it revokes the caller's
    session) last, so they do not disturb the other calls."""
    method, path, _ = route
    rank = 2 if path.endswith("/logout") else int(path.endswith(("/token", "activate")))
    return (rank, path, method)


@pytest.mark.parametrize("role", list(Role))
def test_browser_websocket_admits_only_alarm_viewers(client, make_account, role):
    from starlette.websockets import WebSocketDisconnect

    from backend.realtime.hub import ALARM_VIEWERS

    account = make_account(role)
    if role in ALARM_VIEWERS:
        with client.websocket_connect("/ws/browser", headers=account.headers) as ws:
            assert ws.receive_json()["type"] == "snapshot"
    else:
        with (
            pytest.raises(WebSocketDisconnect) as closed,
            client.websocket_connect("/ws/browser", headers=account.headers) as ws,
        ):
            ws.receive_json()
        assert closed.value.code == 4403


def test_browser_websocket_refuses_a_robot_token(client, robot):
    from starlette.websockets import WebSocketDisconnect

    with (
        pytest.raises(WebSocketDisconnect) as closed,
        client.websocket_connect(
            "/ws/browser", headers={"Authorization": f"Bearer {ROBOT_TOKEN}"}
        ) as ws,
    ):
        ws.receive_json()
    assert closed.value.code == 4401
