"""`vigil-robot simulate` (what `make run` and docker-compose start) against the real backend."""

from __future__ import annotations

import json
import subprocess
import sys

from backend.db import make_engine, make_session_factory, transaction
from backend.models import Robot
from backend.security import hash_robot_token
from tests.support.live_backend import REPO_ROOT, ROBOT_ID, ROBOT_TOKEN

from .conftest import query


def test_simulated_fleet_streams_generated_transports_marked_as_ground_truth(backend, tmp_path):
    engine = make_engine(backend.database_url)
    with transaction(make_session_factory(engine)) as session:
        session.add(
            Robot(id="robot-b", name="B", ward="ward-a", token_hash=hash_robot_token("token-b"))
        )
    engine.dispose()
    tokens = tmp_path / "tokens.json"
    tokens.write_text(json.dumps({ROBOT_ID: ROBOT_TOKEN, "robot-b": "token-b"}))
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "robot_agent.cli",
            "simulate",
            "--backend",
            backend.robot_ws_url,
            "--robots",
            "2",
            "--tokens-file",
            str(tokens),
            "--transports",
            "1",
            "--duration-s",
            "4",
            "--speed",
            "0",
            "--outbox-dir",
            str(tmp_path / "outboxes"),
            "--models-dir",
            str(tmp_path / "models"),
        ],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    for robot_id in (ROBOT_ID, "robot-b"):
        ((count, distinct, first, last),) = query(
            backend,
            "SELECT COUNT(*), COUNT(DISTINCT seq), MIN(seq), MAX(seq) FROM frames "
            "WHERE robot_id = ?",
            robot_id,
        )
        assert count == distinct == last + 1 and first == 0 and count >= 100
        versions = query(
            backend, "SELECT DISTINCT model_version FROM frames WHERE robot_id = ?", robot_id
        )
        assert versions == [("generated-ground-truth",)]
        ((patient, location, ended),) = query(
            backend,
            "SELECT patient, location, ended_at FROM transports WHERE robot_id = ?",
            robot_id,
        )
        assert patient.startswith("GEN-") and "GENERATED" in location and ended is not None
        ((running,),) = query(
            backend, "SELECT running_model_version FROM robots WHERE id = ?", robot_id
        )
        assert running == "generated-ground-truth"
    assert "acknowledged every frame" in result.stderr
