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


# -- role x ward x resource (issue 18, item 2) ------------------------------------------------
#
# Two wards, each with a robot, a transport (patient, location), the video it recorded (with
# frames) and an Emergency alarm; and a recording no robot made (a data set: no ward). Every
# caller (each role confined to ward-a, a nurse of ward-b, a nurse without a ward) reads each
# resource through every route that returns it. The rule (backend/wards.py): a nurse with a
# ward sees that ward only; everyone else sees every ward. Lists leave out what the caller may
# not see; a single resource of another ward answers 404. Routes the role may not call at all
# answer 403 (the table above).

WARD_OF_ROBOT = {"robot-a": "ward-a", "robot-b": "ward-b"}
OTHER_ROBOT_TOKEN = "robot-b-token"


def _expected_visible(role: Role, ward: str | None, resource_ward: str | None) -> bool:
    if role == Role.NURSE and ward is not None:
        return resource_ward == ward
    return True


@pytest.fixture
def two_wards(client, robot, session_factory) -> dict:
    """robot-a (ward-a) and robot-b (ward-b) each stream a transport with an Emergency."""
    from backend.db import transaction
    from backend.models import Robot, Video
    from backend.security import hash_robot_token
    from tests.backend.test_first_alarm import frame
    from vigil.protocol import FrameBatch, Hello, TransportStart

    with transaction(session_factory) as session:
        session.add(
            Robot(
                id="robot-b",
                name="B",
                ward="ward-b",
                token_hash=hash_robot_token(OTHER_ROBOT_TOKEN),
            )
        )
        session.add(Video(name="dataset-1", source="urfd", mode="walking"))
    for robot_id, token in (("robot-a", ROBOT_TOKEN), ("robot-b", OTHER_ROBOT_TOKEN)):
        transport = f"t-{robot_id}"
        with client.websocket_connect("/ws/robot") as ws:
            ws.send_text(Hello(robot_id=robot_id, token=token).model_dump_json())
            assert ws.receive_json()["type"] == "welcome"
            ws.send_text(
                TransportStart(
                    transport_id=transport,
                    mode="walking",
                    ts=0.0,
                    patient=f"P-{robot_id}",
                    location=f"room of {robot_id}",
                ).model_dump_json()
            )
            frames = [frame(0, transport=transport), frame(1, "emergency", transport)]
            ws.send_text(FrameBatch(frames=frames).model_dump_json())
            assert ws.receive_json() == {"type": "ack", "seq": 1}
    with session_factory() as session:
        videos = {v.robot_id: v.id for v in session.query(Video)}
    from backend.models import Alarm

    with session_factory() as session:
        alarms = {a.robot_id: a.id for a in session.query(Alarm)}
    assert set(alarms) == set(WARD_OF_ROBOT)
    return {"videos": videos, "alarms": alarms}


def test_every_resource_carrying_a_ward_is_scoped_by_role_and_ward(client, make_account, two_wards):
    callers = [make_account(role, ward="ward-a") for role in Role]
    callers += [
        make_account(Role.NURSE, ward="ward-b"),
        make_account(Role.NURSE, ward=None),
    ]
    videos, alarms = two_wards["videos"], two_wards["alarms"]
    resource_wards = {**WARD_OF_ROBOT, None: None}  # robot id (None: the data set) -> ward
    # route template -> (concrete path, the ward of what it returns) for single resources
    singles = [("/api/robots/{robot_id}", f"/api/robots/{r}", w) for r, w in WARD_OF_ROBOT.items()]
    singles += [
        ("/api/transports/{transport_id}", f"/api/transports/t-{r}", w)
        for r, w in WARD_OF_ROBOT.items()
    ]
    singles += [
        ("/api/alarms/{alarm_id}", f"/api/alarms/{alarms[r]}", w) for r, w in WARD_OF_ROBOT.items()
    ]
    for robot_id, ward in resource_wards.items():
        video = videos[robot_id]
        singles += [
            ("/api/videos/{video_id}", f"/api/videos/{video}", ward),
            ("/api/videos/{video_id}/frames", f"/api/videos/{video}/frames", ward),
            (
                "/api/labelling/videos/{video_id}/rgb/{frame}",
                f"/api/labelling/videos/{video}/rgb/0",
                ward,
            ),
        ]
    # list route -> (how to read the ids it returned, id -> ward)
    lists = {
        "/api/robots": (lambda body: {r["id"] for r in body}, WARD_OF_ROBOT),
        "/api/fleet": (lambda body: {r["id"] for r in body}, WARD_OF_ROBOT),
        "/api/transports": (
            lambda body: {t["id"] for t in body},
            {f"t-{r}": w for r, w in WARD_OF_ROBOT.items()},
        ),
        "/api/videos": (
            lambda body: {v["id"] for v in body},
            {videos[r]: w for r, w in resource_wards.items()},
        ),
        "/api/alarms": (
            lambda body: {a["id"] for a in body},
            {alarms[r]: w for r, w in WARD_OF_ROBOT.items()},
        ),
        "/api/handover": (
            lambda body: {row["alarm"]["id"] for row in body["alarms"]},
            {alarms[r]: w for r, w in WARD_OF_ROBOT.items()},
        ),
        "/api/handover.csv": (
            lambda body: {int(line.split(",")[1]) for line in body.splitlines()[3:]},
            {alarms[r]: w for r, w in WARD_OF_ROBOT.items()},
        ),
    }
    failures, checked = [], 0
    for caller in callers:
        who = f"{caller.role.value}@{caller.ward or 'no ward'}"
        for template, (ids_of, ward_of_id) in lists.items():
            response = client.get(template, headers=caller.headers)
            if caller.role not in PERMISSIONS[("GET", template)]:
                if response.status_code != 403:
                    failures.append(f"{who} GET {template}: {response.status_code}, not 403")
                continue
            expected = {
                i for i, w in ward_of_id.items() if _expected_visible(caller.role, caller.ward, w)
            }
            body = response.text if template.endswith(".csv") else response.json()
            got = ids_of(body) & set(ward_of_id)
            checked += 1
            if got != expected:
                failures.append(f"{who} GET {template}: {sorted(got)}, expected {sorted(expected)}")
        for template, path, ward in singles:
            response = client.get(path, headers=caller.headers)
            if caller.role not in PERMISSIONS[("GET", template)]:
                if response.status_code != 403:
                    failures.append(f"{who} GET {path}: {response.status_code}, not 403")
                continue
            checked += 1
            visible = _expected_visible(caller.role, caller.ward, ward)
            detail = response.json().get("detail", "") if response.status_code != 200 else ""
            # The robots' videos have no RGB clip: a visible one says so, a hidden one is not
            # found at all.
            shown = response.status_code == 200 or "has no RGB clip" in str(detail)
            if shown != visible or (not visible and response.status_code != 404):
                failures.append(
                    f"{who} GET {path}: {response.status_code} {detail!r}, expected "
                    f"{'visible' if visible else '404'}"
                )
    assert not failures, "\n".join(failures)
    assert checked >= 90  # the matrix really ran


def test_a_ward_nurse_reads_nothing_of_another_wards_transport(client, make_account, two_wards):
    """The issue's repro, spelled out: patient and location of ward-b stay in ward-b."""
    nurse = make_account(Role.NURSE, ward="ward-a", username="nurse-3a")
    listed = client.get("/api/transports", headers=nurse.headers).json()
    assert [t["patient"] for t in listed] == ["P-robot-a"]
    other = client.get("/api/transports/t-robot-b", headers=nurse.headers)
    assert other.status_code == 404 and "P-robot-b" not in other.text
    video_b = two_wards["videos"]["robot-b"]
    assert client.get(f"/api/videos/{video_b}/frames", headers=nurse.headers).status_code == 404
    own = client.get(f"/api/videos/{two_wards['videos']['robot-a']}/frames", headers=nurse.headers)
    assert own.status_code == 200 and len(own.json()) == 2
    assert client.get("/api/robots?", headers=nurse.headers).json()[0]["id"] == "robot-a"
