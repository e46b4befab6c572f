"""A model reaches only robots that feed what it needs; each robot whose model needs more than
keypoints keeps its mode's keypoints-only fallback, which cannot be rolled away."""

from __future__ import annotations

import json

import anyio
from sqlalchemy import select

from backend import models
from backend.db import transaction
from backend.models import Deployment, Robot, Role
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.registry.conftest import FEEDS_ALL
from tests.registry_fixtures import derive_model
from vigil.inputs import describe_missing
from vigil.protocol import Heartbeat, Hello


def set_inputs(session_factory, **inputs) -> None:
    with transaction(session_factory) as session:
        for robot_id, value in inputs.items():
            session.get(Robot, robot_id.replace("_", "-")).inputs = value


def promote(client, engineer, model_id: int, **body):
    return client.post(f"/api/models/{model_id}/promote", headers=engineer.headers, json=body)


def assigned(session_factory) -> dict[str, int | None]:
    with session_factory() as session:
        return {r.id: r.assigned_model_id for r in session.scalars(select(Robot))}


def test_a_floor_model_is_refused_for_a_robot_that_cannot_feed_it_and_a_keypoints_model_is_not(
    client,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    keypoints_model_dir,
    session_factory,
):
    engineer = make_account(Role.ENGINEER)
    set_inputs(session_factory, robot_c=None, robot_d=["keypoints", "depth"])  # c: older agent
    floor = register(trained_model_dir)  # feature set "full": keypoints and floor measures
    keypoints = register(keypoints_model_dir)
    models = {m["id"]: m for m in client.get("/api/models", headers=engineer.headers).json()}
    assert models[floor]["inputs"] == ["keypoints", "floor"]
    assert (models[keypoints]["inputs"], models[keypoints]["keypoints_only"]) == (
        ["keypoints"],
        True,
    )

    refused = promote(client, engineer, floor, scope="robot", target="robot-c")
    assert refused.status_code == 409
    assert refused.json()["detail"] == describe_missing("rf-test-1", ["floor"], "robot-c")
    assert refused.json()["detail"] == (
        "robot robot-c cannot feed model rf-test-1: it has no floor measures"
    )
    # A ward with one robot that cannot: refused as a whole, naming it.
    ward = promote(client, engineer, floor, scope="ward", target="ward-a")
    assert ward.status_code == 409
    assert ward.json()["detail"].startswith("1 of 3 robots in the scope cannot feed model")
    assert "robot robot-c cannot feed" in ward.json()["detail"]
    fleet_wide = promote(client, engineer, floor, scope="fleet")
    assert fleet_wide.status_code == 409 and "2 of 4 robots" in fleet_wide.json()["detail"]
    shadow = client.post(
        f"/api/models/{floor}/shadow",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-d"},
    )
    assert shadow.status_code == 409 and "robot-d" in shadow.json()["detail"]
    canary = promote(
        client,
        engineer,
        floor,
        scope="ward",
        target="ward-a",
        canary_robot_id="robot-c",
        only_capable=True,
    )
    assert canary.status_code == 409 and "canary_robot_id" in canary.json()["detail"]
    with session_factory() as session:
        assert session.scalars(select(Deployment)).first() is None
    assert set(assigned(session_factory).values()) == {None}

    # Which robots qualify, for the promotion page.
    view = client.get("/api/fleet", params={"model_id": floor}, headers=engineer.headers).json()
    rows = {
        r["id"]: (r["inputs"], r["inputs_reported"], r["qualifies"], r["missing_inputs"])
        for r in view
    }
    assert rows == {
        "robot-a": (FEEDS_ALL, True, True, []),
        "robot-b": (FEEDS_ALL, True, True, []),
        "robot-c": (["keypoints"], False, False, ["floor"]),
        "robot-d": (["keypoints", "depth"], True, False, ["floor"]),
    }
    assert (
        client.get("/api/fleet", params={"model_id": 999_999}, headers=engineer.headers).status_code
        == 404
    )

    # The keypoints-only model goes anywhere.
    ok = promote(client, engineer, keypoints, scope="robot", target="robot-c")
    assert ok.status_code == 201, ok.text
    assert ok.json()["status"] == "active"
    # only_capable narrows a ward to the robots that can feed the model.
    narrowed = promote(client, engineer, floor, scope="ward", target="ward-a", only_capable=True)
    assert narrowed.status_code == 201, narrowed.text
    deployment = narrowed.json()
    assert deployment["rollout"]["robots"] == ["robot-a", "robot-b"]
    assert deployment["rollout"]["skipped"] == {
        "robot-c": describe_missing("rf-test-1", ["floor"], "robot-c")
    }
    # The canary's robot reports the version; robot-b said meanwhile it lost its floor
    # measures: the advance is refused, naming it.
    with transaction(session_factory) as session:
        session.get(Robot, "robot-a").running_model_version = "rf-test-1"
    set_inputs(session_factory, robot_b=["keypoints", "depth"])
    advance = client.post(f"/api/deployments/{deployment['id']}/advance", headers=engineer.headers)
    assert advance.status_code == 200, advance.text
    # only_capable applies at the advance too: robot-b is skipped, not refused.
    assert set(advance.json()["rollout"]["skipped"]) == {"robot-b", "robot-c"}
    assert assigned(session_factory) == {
        "robot-a": floor,
        "robot-b": None,
        "robot-c": keypoints,
        "robot-d": None,
    }


def test_an_advance_to_a_robot_that_can_no_longer_feed_the_model_is_refused(
    client, make_account, fleet, urfd_db, register, trained_model_dir, session_factory
):
    engineer = make_account(Role.ENGINEER)
    floor = register(trained_model_dir)
    deployment = promote(client, engineer, floor, scope="ward", target="ward-a").json()
    assert deployment["status"] == "canary"
    with transaction(session_factory) as session:
        session.get(Robot, "robot-a").running_model_version = "rf-test-1"
    set_inputs(session_factory, robot_b=["keypoints"])
    advance = client.post(f"/api/deployments/{deployment['id']}/advance", headers=engineer.headers)
    assert advance.status_code == 409
    assert (
        "robot robot-b cannot feed model rf-test-1: it has no floor measures"
        in (advance.json()["detail"])
    )
    assert assigned(session_factory)["robot-b"] is None


def test_robots_keep_the_keypoints_only_fallback_which_cannot_be_rolled_away(
    client,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    keypoints_model_dir,
    tmp_path,
    session_factory,
):
    engineer = make_account(Role.ENGINEER)
    floor = register(trained_model_dir)
    kp1 = register(keypoints_model_dir)
    kp2 = register(derive_model(keypoints_model_dir, tmp_path / "kp2", "rf-kp-test-2"))
    robot_a = {"X-Robot-Id": "robot-a", "Authorization": f"Bearer {ROBOT_TOKEN}"}
    assert promote(client, engineer, floor, scope="robot", target="robot-a").status_code == 201
    fleet_view = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}
    # No keypoints-only model is promoted yet: no fallback, and robot-a may not fetch one.
    assert fleet_view["robot-a"]["fallback_version"] is None
    assert client.get("/api/robot/models/rf-kp-test-1/file", headers=robot_a).status_code == 403

    first = promote(client, engineer, kp1, scope="robot", target="robot-d").json()
    fleet_view = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}
    assert fleet_view["robot-a"]["fallback_version"] == "rf-kp-test-1"
    assert fleet_view["robot-a"]["target_feedable"] is True
    assert fleet_view["robot-d"]["fallback_version"] is None  # its model needs keypoints only
    assert client.get("/api/robot/models/rf-kp-test-1/file", headers=robot_a).status_code == 200

    # After welcome: the assigned model, then the fallback beside it.
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(
            Hello(
                robot_id="robot-a", token=ROBOT_TOKEN, inputs=FEEDS_ALL, running_model="rf-test-1"
            ).model_dump_json()
        )
        assert json.loads(ws.receive_text())["type"] == "welcome"
        fallback = json.loads(ws.receive_text())  # it runs rf-test-1 already: only the fallback
        assert (fallback["type"], fallback["version"], fallback["fallback"]) == (
            "assign_model",
            "rf-kp-test-1",
            True,
        )
        assert fallback["manifest"]["inputs"] == ["keypoints"] and fallback["url"].endswith(
            "/api/robot/models/rf-kp-test-1/file"
        )

        # The last keypoints-only walking model in production cannot be rolled back.
        refused = client.post(
            f"/api/deployments/{first['id']}/rollback", headers=engineer.headers, json={}
        )
        assert refused.status_code == 409
        assert (
            "rf-kp-test-1 is the last promoted keypoints-only walking model"
            in (refused.json()["detail"])
        )
        # A newer keypoints-only model becomes the fallback: robot-a hears of it (here through
        # the reconcile loop, as for a change made by another replica or the worker).
        assert promote(client, engineer, kp2, scope="robot", target="robot-b").status_code == 201
        pushed = client.portal.call(client.app.state.services.assignments.reconcile)
        assert pushed in (["robot-a"], [])  # [] if the app's own reconcile loop came first
        newer = json.loads(ws.receive_text())
        assert (newer["version"], newer["fallback"]) == ("rf-kp-test-2", True)
        assert (
            client.portal.call(client.app.state.services.assignments.reconcile) == []
        )  # sent once

    # Now the first keypoints-only model may go.
    rolled = client.post(
        f"/api/deployments/{first['id']}/rollback", headers=engineer.headers, json={}
    )
    assert rolled.status_code == 200, rolled.text
    models = {
        m["id"]: m["status"] for m in client.get("/api/models", headers=engineer.headers).json()
    }
    assert (models[kp1], models[kp2]) == ("retired", "production")
    fleet_view = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}
    assert fleet_view["robot-a"]["fallback_version"] == "rf-kp-test-2"


def test_rollback_gives_a_robot_that_had_no_model_its_fallback_not_nothing(
    client,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    keypoints_model_dir,
    session_factory,
):
    engineer = make_account(Role.ENGINEER)
    keypoints = register(keypoints_model_dir)
    floor = register(trained_model_dir)
    assert promote(client, engineer, keypoints, scope="robot", target="robot-a").status_code == 201
    deployment = promote(client, engineer, floor, scope="robot", target="robot-d").json()
    assert assigned(session_factory)["robot-d"] == floor
    with transaction(session_factory) as session:  # robot-d runs the floor model
        robot = session.get(Robot, "robot-d")
        robot.running_model_version = session.get(models.ModelVersion, floor).version
    rolled = client.post(
        f"/api/deployments/{deployment['id']}/rollback",
        headers=engineer.headers,
        json={"reason": "wrong model"},
    )
    assert rolled.status_code == 200, rolled.text
    # robot-d had no model before: it gets the keypoints-only fallback, not "nothing" (which
    # would have left it running the rolled-back model).
    assert assigned(session_factory)["robot-d"] == keypoints
    assert rolled.json()["rollout"]["restored"] == {"robot-d": keypoints}
    row = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}["robot-d"]
    assert row["in_sync"] is False  # it still runs the rolled-back version until it switches


def test_a_robot_with_no_target_is_in_sync_only_when_it_runs_nothing():
    from backend.registry.queries import in_sync

    assert in_sync(None, Robot(id="r", running_model_version=None)) is True
    assert in_sync(None, Robot(id="r", running_model_version="rolled-back-1")) is False


def test_reconcile_believes_the_robots_hello_over_a_stored_running_model_that_lags(
    client,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    session_factory,
):
    """The frame writer stores what a robot runs after its welcome; the reconcile loop may run
    in between and must not resend a model the robot said it already runs."""
    engineer = make_account(Role.ENGINEER)
    floor = register(trained_model_dir)
    assert promote(client, engineer, floor, scope="robot", target="robot-a").status_code == 201
    pusher = client.app.state.services.assignments
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(
            Hello(
                robot_id="robot-a", token=ROBOT_TOKEN, inputs=FEEDS_ALL, running_model="rf-test-1"
            ).model_dump_json()
        )
        assert json.loads(ws.receive_text())["type"] == "welcome"
        # What the writer has not stored yet (or a replica stored before): nothing runs.
        with transaction(session_factory) as session:
            session.get(Robot, "robot-a").running_model_version = None
        assert client.portal.call(pusher.reconcile) == []
        # A heartbeat naming another model counts as soon as it is received.
        ws.send_text(Heartbeat(ts=1.0, running_model="something-else").model_dump_json())
        for _ in range(200):
            if pusher.sent.running.get("robot-a", (None,))[0] == "something-else":
                break
            client.portal.call(anyio.sleep, 0.01)
        assert pusher.sent.running["robot-a"][0] == "something-else"
        with transaction(session_factory) as session:
            session.get(Robot, "robot-a").running_model_version = "rf-test-1"
        pusher.sent.assignments.pop("robot-a", None)  # not a resend "too soon"
        assert client.portal.call(pusher.reconcile) == ["robot-a"]
        resent = json.loads(ws.receive_text())
        assert (resent["type"], resent["version"]) == ("assign_model", "rf-test-1")
