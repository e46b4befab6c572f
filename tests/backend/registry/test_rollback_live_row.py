"""After a rollback a live deployment row says what the robots run now (issue 35)."""

from __future__ import annotations

from sqlalchemy import select

from backend.db import transaction
from backend.models import Robot, Role, User
from tests.registry_fixtures import second_version


def _deployments(client, headers) -> list[dict]:
    return sorted(client.get("/api/deployments", headers=headers).json(), key=lambda d: d["id"])


def test_a_rollback_leaves_a_live_row_for_the_restored_model(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path, session_factory
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.55))

    def roll_out(model_id: int) -> dict:
        started = client.post(
            f"/api/models/{model_id}/promote", headers=engineer.headers, json={"scope": "fleet"}
        ).json()
        version = started["model_version"]
        with transaction(session_factory) as session:  # the canary reports the new version
            session.get(Robot, started["rollout"]["canary"]).running_model_version = version
        advanced = client.post(
            f"/api/deployments/{started['id']}/advance", headers=engineer.headers
        )
        assert advanced.status_code == 200, advanced.text
        return advanced.json()

    first = roll_out(v1)
    second = roll_out(v2)
    statuses = {d["id"]: d["status"] for d in _deployments(client, engineer.headers)}
    assert statuses == {first["id"]: "superseded", second["id"]: "active"}

    rolled = client.post(
        f"/api/deployments/{second['id']}/rollback",
        headers=engineer.headers,
        json={"reason": "v2 misses falls on ward-b"},
    )
    assert rolled.status_code == 200, rolled.text
    with session_factory() as session:
        assert {r.assigned_model_id for r in session.scalars(select(Robot))} == {v1}

    rows = _deployments(client, engineer.headers)
    live = [d for d in rows if d["status"] in ("canary", "active")]
    assert len(live) == 1, rows
    (now,) = live
    assert now["id"] not in (first["id"], second["id"])
    assert (now["model_version_id"], now["scope"], now["target"]) == (v1, "fleet", None)
    assert now["shadow"] is False
    assert sorted(now["rollout"]["assigned"]) == sorted(fleet)
    assert now["previous_model_version_id"] == v2
    with session_factory() as session:
        signer = session.scalars(select(User).where(User.username == engineer.username)).one()
        assert now["created_by_id"] == signer.id
    assert "v2 misses falls on ward-b" in now["comment"]
    assert f"rollback of deployment {second['id']}" in now["comment"]
    assert rolled.json()["rollout"]["restored_by"] == [now["id"]]
    statuses = {d["id"]: d["status"] for d in rows}
    assert statuses[first["id"]] == "superseded" and statuses[second["id"]] == "rolled_back"


def test_a_rollback_of_a_canary_adds_no_row_when_a_live_one_holds_the_robots(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path, session_factory
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.55))
    first = client.post(
        f"/api/models/{v1}/promote",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-a"},
    ).json()
    assert first["status"] == "active"
    second = client.post(
        f"/api/models/{v2}/promote",
        headers=engineer.headers,
        json={"scope": "ward", "target": "ward-a"},
    ).json()
    assert second["status"] == "canary"  # robot-a, the canary; the first stays live
    client.post(
        f"/api/deployments/{second['id']}/rollback",
        headers=engineer.headers,
        json={"reason": "not yet"},
    ).raise_for_status()
    rows = _deployments(client, engineer.headers)
    assert [(d["id"], d["status"]) for d in rows] == [
        (first["id"], "active"),
        (second["id"], "rolled_back"),
    ]
