"""The simulated fleet (GENERATED transports with falls) against the real backend, with the
real classifier and with the generator's ground truth."""

from __future__ import annotations

import asyncio

import pytest
from sqlalchemy import func, select

from backend.db import transaction
from backend.models import Frame
from backend.models.robots import Robot
from backend.process import BackendProcess
from backend.security import hash_robot_token
from robot_agent.fleet import run_fleet


@pytest.fixture
def backend_env(database_url, tmp_path) -> dict[str, str]:
    return {
        "VIGIL_DATABASE_URL": database_url,
        "VIGIL_SECRET_KEY": "fleet-secret",
        "VIGIL_FRONTEND_DIR": str(tmp_path / "no-frontend"),
    }


@pytest.mark.timeout(120)
def test_fleet_streams_model_and_ground_truth_decisions(
    backend_env, session_factory, trained_model_dir, tmp_path
):
    tokens = {f"robot-{i}": f"token-{i}-for-the-fleet-test" for i in (1, 2)}
    with transaction(session_factory) as session:
        for robot_id, token in tokens.items():
            session.add(Robot(id=robot_id, name=robot_id, ward="ward-a",
                              token_hash=hash_robot_token(token)))  # fmt: skip
    with BackendProcess(backend_env, log_path=tmp_path / "backend.log") as backend:
        url = backend.ws + "/ws/robot"
        counts = asyncio.run(run_fleet(url, tokens, 2, tmp_path / "fleet", trained_model_dir,
                                       speed=15, transports=1, duration_s=8))  # fmt: skip
        assert set(counts) == set(tokens) and min(counts.values()) > 150
        with session_factory() as session:
            stored = dict(session.execute(
                select(Frame.robot_id, func.count()).group_by(Frame.robot_id)).all())  # fmt: skip
            versions = set(session.scalars(select(Frame.model_version).distinct()))
        assert stored == counts
        assert versions == {"rf-test-1"}

        truth = asyncio.run(run_fleet(url, {"robot-1": tokens["robot-1"]}, 1, tmp_path / "gt",
                                      ground_truth=True, speed=15, transports=1,
                                      duration_s=8))  # fmt: skip
        with session_factory() as session:
            decisions = set(
                session.scalars(
                    select(Frame.decision).where(Frame.model_version == "generated-ground-truth")
                )
            )
            truth_frames = session.scalar(select(func.count()).select_from(Frame).where(
                Frame.model_version == "generated-ground-truth"))  # fmt: skip
        assert truth["robot-1"] > 150
        # a fresh outbox for a robot the backend knows: renumbered, nothing taken for a duplicate
        assert truth_frames == truth["robot-1"]
        assert "emergency" in {str(d) for d in decisions}  # every generated transport has one
