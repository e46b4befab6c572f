"""Gate, staged rollout, rollback (manual and automatic) and the fleet view through the API."""

from __future__ import annotations

from datetime import timedelta

from sqlalchemy import func, select

from backend.db import transaction
from backend.models import Alarm, AlarmKind, AlarmPriority, AlarmState, Deployment, Robot, Role
from backend.models._types import utcnow
from backend.registry.sweeps import automatic_rollback
from tests.backend.conftest import ROBOT_TOKEN
from tests.registry_fixtures import TRAIN, derive_model, second_version

SPLIT_CHECK = "judged on gold recordings it was not trained on"


def test_the_gate_blocks_a_model_that_misses_a_fall(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path, session_factory
):
    engineer = make_account(Role.ENGINEER)
    # The same graph with a 10 s delay: no Emergency run in the gold recordings lasts that long.
    blind = register(
        derive_model(trained_model_dir, tmp_path / "blind", "blind-1", delay_ms=10_000)
    )
    gate = client.get(f"/api/models/{blind}/gate", headers=engineer.headers).json()
    assert gate["passed"] is False
    fall_check = next(c for c in gate["checks"] if c["name"] == "misses no fall of the gold set")
    assert fall_check["passed"] is False and fall_check["detail"].startswith("0 of 2 falls")
    assert "fall-07" in fall_check["detail"]
    split = next(c for c in gate["checks"] if c["name"] == SPLIT_CHECK)
    assert split["passed"] and split["detail"] == (
        "none of the 4 gold recordings is among its 12 training recordings"
    )

    response = client.post(
        f"/api/models/{blind}/promote", headers=engineer.headers, json={"scope": "fleet"}
    )
    assert response.status_code == 409
    assert "gate failed: misses no fall of the gold set" in response.json()["detail"]
    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Deployment)) == 0
        assert all(r.assigned_model_id is None for r in session.scalars(select(Robot)))

    good = register(trained_model_dir)
    assert client.get(f"/api/models/{good}/gate", headers=engineer.headers).json()["passed"]


def test_the_gate_refuses_a_model_trained_on_its_gold_recordings_naming_them(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path, session_factory
):
    """Gold-set figures of a model trained on gold recordings are training figures: the gate
    refuses it and names the recordings; a model that records no training recordings cannot
    show it never saw the gold set and is refused for that."""
    engineer = make_account(Role.ENGINEER)
    overlapping = register(
        derive_model(
            trained_model_dir,
            tmp_path / "overlap",
            "overlap-1",
            training_recordings=[*TRAIN, "fall-08", "adl-07"],
        )
    )
    unknown = register(
        derive_model(trained_model_dir, tmp_path / "unknown", "unknown-1", training_recordings=None)
    )
    gate = client.get(f"/api/models/{overlapping}/gate", headers=engineer.headers).json()
    split = next(c for c in gate["checks"] if c["name"] == SPLIT_CHECK)
    assert gate["passed"] is False and split["passed"] is False and split["value"] == 2
    assert split["detail"] == "2 of 4 gold recordings were also training data: adl-07, fall-08"
    assert gate["split"] == {
        "gold_recordings": 4,
        "training_recordings": 14,
        "overlap": ["adl-07", "fall-08"],
    }
    response = client.post(
        f"/api/models/{overlapping}/promote", headers=engineer.headers, json={"scope": "fleet"}
    )
    assert response.status_code == 409
    assert f"gate failed: {SPLIT_CHECK}" in response.json()["detail"]
    assert "adl-07, fall-08" in response.json()["detail"]

    gate = client.get(f"/api/models/{unknown}/gate", headers=engineer.headers).json()
    split = next(c for c in gate["checks"] if c["name"] == SPLIT_CHECK)
    assert gate["passed"] is False and split["passed"] is False
    assert split["detail"].startswith("training recordings unknown")
    assert gate["split"]["overlap"] is None and gate["split"]["training_recordings"] is None
    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Deployment)) == 0


def test_staged_rollout_canary_then_ward_then_rollback_restores_each_robot(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path, session_factory
):
    engineer = make_account(Role.ENGINEER)
    nurse = make_account(Role.NURSE)
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.55))

    assert (
        client.post(
            f"/api/models/{v1}/promote", headers=nurse.headers, json={"scope": "fleet"}
        ).status_code
        == 403
    )
    bad_scope = client.post(
        f"/api/models/{v1}/promote",
        headers=engineer.headers,
        json={"scope": "ward", "target": "ward-z"},
    )
    assert bad_scope.status_code == 422 and "no robot in ward ward-z" in bad_scope.json()["detail"]

    deployment = client.post(
        f"/api/models/{v1}/promote",
        headers=engineer.headers,
        json={"scope": "ward", "target": "ward-a", "comment": "first model"},
    ).json()
    assert deployment["status"] == "canary" and deployment["rollout"]["canary"] == "robot-a"
    assert deployment["gate_report"]["passed"] is True
    fleet_view = {r["id"]: r for r in client.get("/api/fleet", headers=engineer.headers).json()}
    assert fleet_view["robot-a"]["target_version"] == "rf-test-1"
    assert fleet_view["robot-a"]["in_sync"] is False
    assert fleet_view["robot-b"]["target_version"] is None
    listed = {m["id"]: m for m in client.get("/api/models", headers=engineer.headers).json()}
    assert (listed[v1]["canary_robot"], listed[v1]["robots_assigned"]) == ("robot-a", 1)
    assert listed[v1]["robots_in_fleet"] == 4 and listed[v2]["canary_robot"] is None

    advance = client.post(f"/api/deployments/{deployment['id']}/advance", headers=engineer.headers)
    assert advance.status_code == 409 and "runs no model" in advance.json()["detail"]
    with transaction(session_factory) as session:  # the canary reports the new version
        session.get(Robot, "robot-a").running_model_version = "rf-test-1"
    advanced = client.post(
        f"/api/deployments/{deployment['id']}/advance", headers=engineer.headers
    ).json()
    assert advanced["status"] == "active"
    with session_factory() as session:
        assigned = {r.id: r.assigned_model_id for r in session.scalars(select(Robot))}
    assert assigned == {"robot-a": v1, "robot-b": v1, "robot-c": v1, "robot-d": None}

    # v2 to the whole fleet, canary robot-b; then one click rolls it back.
    second = client.post(
        f"/api/models/{v2}/promote",
        headers=engineer.headers,
        json={"scope": "fleet", "canary_robot_id": "robot-b"},
    ).json()
    assert second["status"] == "canary" and second["previous_model_version_id"] == v1
    with session_factory() as session:
        assert session.get(Robot, "robot-b").assigned_model_id == v2
    rolled = client.post(
        f"/api/deployments/{second['id']}/rollback",
        headers=engineer.headers,
        json={"reason": "canary looks wrong"},
    ).json()
    assert rolled["status"] == "rolled_back" and "canary looks wrong" in rolled["rollback_reason"]
    with session_factory() as session:
        assigned = {r.id: r.assigned_model_id for r in session.scalars(select(Robot))}
    assert assigned == {"robot-a": v1, "robot-b": v1, "robot-c": v1, "robot-d": None}
    models = {m["id"]: m for m in client.get("/api/models", headers=engineer.headers).json()}
    assert models[v1]["status"] == "production" and models[v2]["status"] == "retired"
    assert (models[v1]["robots_assigned"], models[v1]["canary_robot"]) == (3, None)
    again = client.post(
        f"/api/deployments/{second['id']}/rollback", headers=engineer.headers, json={}
    )
    assert again.status_code == 409

    comparison = client.get(f"/api/models/compare?a={v1}&b={v2}", headers=engineer.headers).json()
    rows = {r["metric"]: r for r in comparison["rows"]}
    assert rows["threshold"]["b"] == 0.55 and len(comparison["events"]) == 4
    detail = client.get(f"/api/models/{v1}", headers=engineer.headers).json()
    assert "roc_pr" in detail["plots"]
    png = client.get(f"/api/models/{v1}/plots/roc_pr", headers=engineer.headers)
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")


def test_second_approver_is_required_when_configured(
    client, make_account, fleet, urfd_db, register, trained_model_dir, session_factory
):
    client.app.state.services.settings.require_second_approver = True
    first = make_account(Role.ENGINEER, username="eng-1")
    second = make_account(Role.ENGINEER, username="eng-2")
    v1 = register(trained_model_dir)
    pending = client.post(
        f"/api/models/{v1}/promote",
        headers=first.headers,
        json={"scope": "robot", "target": "robot-c"},
    ).json()
    assert pending["status"] == "pending_approval"
    with session_factory() as session:
        assert session.get(Robot, "robot-c").assigned_model_id is None
    self_approval = client.post(f"/api/deployments/{pending['id']}/approve", headers=first.headers)
    assert self_approval.status_code == 409
    approved = client.post(
        f"/api/deployments/{pending['id']}/approve", headers=second.headers
    ).json()
    assert approved["status"] == "active" and approved["second_approver_id"] is not None
    with session_factory() as session:
        assert session.get(Robot, "robot-c").assigned_model_id == v1


def test_automatic_rollback_when_nurses_reject_too_many_alarms(
    client,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    tmp_path,
    session_factory,
    factory,
    worker_settings,
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.5))
    client.post(
        f"/api/models/{v1}/promote",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-d"},
    )
    new = client.post(
        f"/api/models/{v2}/promote",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-d"},
    ).json()
    assert new["status"] == "active"

    def alarms(verdicts, version="rf-test-2"):
        with transaction(session_factory) as session:
            for i, verdict in enumerate(verdicts):
                session.add(
                    Alarm(
                        kind=AlarmKind.EMERGENCY,
                        priority=AlarmPriority.HIGH,
                        state=AlarmState.RESOLVED,
                        robot_id="robot-d",
                        transport_key=f"t{i}{version}",
                        ward="ward-b",
                        verdict=verdict,
                        model_version=version,
                        raised_at=utcnow() + timedelta(seconds=1),
                    )
                )

    settings = worker_settings.model_copy(
        update={"false_alarm_budget": 0.5, "false_alarm_min_verdicts": 4}
    )
    alarms(["false_alarm", "false_alarm", "true_emergency"])  # 3 verdicts: too few to act
    automatic_rollback(factory, settings)
    with session_factory() as session:
        assert session.get(Deployment, new["id"]).status == "active"
    alarms(["false_alarm", "false_alarm", "false_alarm"], version="rf-test-1")  # other version
    automatic_rollback(factory, settings)
    with session_factory() as session:
        assert session.get(Deployment, new["id"]).status == "active"
    listed = client.get("/api/deployments", headers=engineer.headers).json()
    shown = next(d for d in listed if d["id"] == new["id"])
    assert (shown["alarms_rejected"], shown["alarms_judged"]) == (2, 3)
    alarms(["false_alarm"])  # 3 of 4 rejected = 75 % > 50 %
    automatic_rollback(factory, settings)
    with session_factory() as session:
        deployment = session.get(Deployment, new["id"])
        assert deployment.status == "rolled_back"
        assert deployment.rollback_reason.startswith("automatic: nurses rejected 3 of 4")
        assert session.get(Robot, "robot-d").assigned_model_id == v1


def test_model_download_needs_the_robot_token_and_an_assignment(
    client, make_account, fleet, urfd_db, register, trained_model_dir
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    url = "/api/robot/models/rf-test-1/file"
    robot = {"X-Robot-Id": "robot-a", "Authorization": f"Bearer {ROBOT_TOKEN}"}
    wrong = {"X-Robot-Id": "robot-a", "Authorization": "Bearer nope"}
    assert client.get(url, headers=wrong).status_code == 401
    assert client.get(url, headers=engineer.headers | {"X-Robot-Id": "robot-a"}).status_code == 401
    not_assigned = client.get(url, headers=robot)
    assert not_assigned.status_code == 403 and "not assigned" in not_assigned.json()["detail"]
    client.post(
        f"/api/models/{v1}/promote",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-a"},
    )
    response = client.get(url, headers=robot)
    assert response.status_code == 200
    import hashlib

    model = client.get(f"/api/models/{v1}", headers=engineer.headers).json()
    assert hashlib.sha256(response.content).hexdigest() == model["sha256"]
    assert response.headers["x-model-sha256"] == model["sha256"]
    manifest = client.get("/api/robot/models/rf-test-1/manifest", headers=robot).json()
    assert manifest["sha256"] == model["sha256"] and manifest["version"] == "rf-test-1"


def test_jobs_api_checks_parameters_and_roles_and_cancels(client, make_account):
    engineer = make_account(Role.ENGINEER)
    annotator = make_account(Role.ANNOTATOR)
    body = {"kind": "whatif", "params": {"model_version_id": 1, "threshold": 2, "delay_ms": 0}}
    bad = client.post("/api/jobs", headers=engineer.headers, json=body)
    assert bad.status_code == 422 and "invalid job parameter threshold" in bad.json()["detail"]
    unknown = client.post(
        "/api/jobs", headers=engineer.headers, json={"kind": "retrain", "params": {"epochs": 3}}
    )
    assert unknown.status_code == 422 and "epochs" in unknown.json()["detail"]
    assert (
        client.post(
            "/api/jobs", headers=annotator.headers, json={"kind": "retrain", "params": {}}
        ).status_code
        == 403
    )
    job = client.post(
        "/api/jobs", headers=engineer.headers, json={"kind": "retrain", "params": {"spec": "rf"}}
    ).json()
    assert job["status"] == "queued" and job["created_by_id"] is not None
    listed = client.get("/api/jobs", headers=engineer.headers).json()
    assert [j["id"] for j in listed] == [job["id"]]
    cancelled = client.post(f"/api/jobs/{job['id']}/cancel", headers=engineer.headers).json()
    assert cancelled["status"] == "cancelled"
    again = client.post(f"/api/jobs/{job['id']}/cancel", headers=engineer.headers)
    assert again.status_code == 409
    detail = client.get(f"/api/jobs/{job['id']}", headers=engineer.headers).json()
    assert "cancelled before it started" in detail["log"]
