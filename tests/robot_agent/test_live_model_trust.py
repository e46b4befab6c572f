"""Issue 18, item 5, against the real backend and the agent's console entry point: a model on
the robot's disk replaced (file and local manifest) by an always-Normal graph is refused at
start; it decides no frame, the nurse board shows a technical alarm saying why, and the fleet
shows the robot not in sync. Once the registry's file can be downloaded, the robot fetches it,
runs it, the alarm clears and the fleet shows the registry's sha256 running."""

from __future__ import annotations

import shutil

import httpx

from backend.db import make_engine, make_session_factory, transaction
from backend.models import Role, User
from robot_agent.models import remember_running
from tests.support.live_backend import PASSWORD, ROBOT_ID
from tests.support.passwords import password_hash
from vigil.model_file import read_manifest

from .conftest import NurseSocket, query, wait_for
from .test_live_models import ENDLESS_GENERATED, assign, running_version, versions_in_seq_order
from .tiny_model import write_upright_model


def fleet_row(backend, token: str) -> dict:
    response = httpx.get(
        f"{backend.base_url}/api/fleet", timeout=10, headers={"Authorization": f"Bearer {token}"}
    )
    return next(r for r in response.json() if r["id"] == ROBOT_ID)


def test_a_tampered_model_on_the_robots_disk_is_refused(backend, agents, tmp_path):
    engine = make_engine(backend.database_url)
    with transaction(make_session_factory(engine)) as session:
        session.add(User(username="eve", password_hash=password_hash(PASSWORD), role=Role.ENGINEER))
    engine.dispose()
    engineer = backend.login("eve")

    # The registry holds upright-7 (assigned to robot-a); its file is not downloadable yet.
    registry_copy = write_upright_model(tmp_path / "store" / "upright-7", "upright-7")
    genuine = read_manifest(registry_copy)[0].sha256
    assign(backend, registry_copy)
    kept = tmp_path / "kept"
    shutil.move(registry_copy, kept)
    # The robot ran upright-7 before; its copy was then replaced, manifest and all.
    robot_models = tmp_path / "robot-models" / ROBOT_ID
    write_upright_model(robot_models / "upright-7", "upright-7", always_normal=True)
    remember_running(robot_models, "upright-7", genuine)  # as the agent noted it

    nurse = NurseSocket(backend)
    shipped = write_upright_model(tmp_path / "shipped", "kp-1", feature_set="keypoints")
    agent = agents(backend, *ENDLESS_GENERATED, "--model-dir", str(shipped))
    alarm = nurse.wait_alarm("detection_degraded", ROBOT_ID, 30)
    assert alarm["priority"] == "technical"
    assert alarm["details"]["assigned_model"] == "upright-7"
    reason = alarm["details"]["reason"]
    assert "refused at start" in reason and genuine in reason and "deciding with kp-1" in reason
    assert alarm["details"]["summary"].startswith("model upright-7 refused")
    wait_for(lambda: len(versions_in_seq_order(backend)) > 50, 30, "frames")
    wait_for(lambda: "download of" in agent.log(), 30, "a download of the registry's file")
    assert "upright-7" not in set(versions_in_seq_order(backend))  # it never decided a frame
    row = fleet_row(backend, engineer)
    assert row["target_version"] == "upright-7" and row["in_sync"] is False
    assert row["running_version"] == "kp-1" and row["running_sha256"] != genuine

    # The registry's file is back: the robot fetches it, runs it and the alarm clears.
    shutil.move(kept, registry_copy)
    wait_for(lambda: running_version(backend) == "upright-7", 30, "upright-7 from the registry")
    wait_for(lambda: fleet_row(backend, engineer)["in_sync"], 30, "the fleet in sync")
    assert fleet_row(backend, engineer)["running_sha256"] == genuine
    wait_for(
        lambda: (
            query(backend, "SELECT state FROM alarms WHERE kind = 'detection_degraded'")
            == [("resolved",)]
        ),
        30,
        "the refusal alarm cleared",
    )
    nurse.close()
