from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from backend.db import transaction
from backend.jobs import queue
from backend.models.jobs import JobKind, JobStatus
from backend.models.robots import Robot
from backend.security import hash_robot_token
from tests.backend.conftest import ROBOT_TOKEN
from tests.registry_fixtures import (
    SMALL_GRID,
    TRAIN,
    factory,
    trained_model_dir,
    urfd_db,
    worker_settings,
)
from tests.support.model_cache import trained_once
from worker.runner import Worker

__all__ = ["factory", "trained_model_dir", "urfd_db", "worker_settings"]


@pytest.fixture(scope="session")
def keypoints_model_dir(tmp_path_factory) -> Path:
    """`rf-kp-test-1`: like `trained_model_dir` but on the keypoints feature set (no floor
    measures), so its manifest needs keypoints only: a robot's fallback."""
    from worker.training.cross_validation import select
    from worker.training.data import from_urfd
    from worker.training.estimators import ModelSpec
    from worker.training.publish import publish
    from worker.training.trainers import SklearnTrainer

    def train(out: Path) -> None:
        data = from_urfd(names=TRAIN)
        grid = {k: v[:1] for k, v in SMALL_GRID.items()}
        trainer = SklearnTrainer(ModelSpec("rf-kp-test", "rf", grid, feature_set="keypoints"))
        selected = select(trainer, data, np.arange(len(data.names)), n_inner=3, stride=2)
        publish(trainer, selected, data, out, version="rf-kp-test-1")

    return trained_once("rf-kp-test", train, tmp_path_factory.mktemp("model") / "rf-kp-test")


@pytest.fixture
def settings(settings):
    # Two ADL recordings in the small gold set: one false alarm is 50 %.
    return settings.model_copy(update={"gate_false_alarm_budget": 0.5})


@pytest.fixture
def register(factory, worker_settings):  # noqa: F811
    """Register a model directory through the worker's register job; returns the model id."""

    def run(model_dir) -> int:
        with transaction(factory) as session:
            job_id = queue.enqueue(session, JobKind.REGISTER, {"path": str(model_dir)}).id
        Worker(worker_settings, factory, sweeps=[]).run_once()
        with factory() as session:
            from backend.models.jobs import Job

            job = session.get(Job, job_id)
            assert job.status == JobStatus.SUCCEEDED, job.log
            return job.result["model_version_id"]

    return run


FEEDS_ALL = ["keypoints", "depth", "floor"]


@pytest.fixture
def fleet(session_factory) -> list[str]:
    """Three robots in ward-a (same token as the `robot` fixture) and one in ward-b; each said
    in its last hello that it feeds keypoints, depth and floor measures (the test models use
    the full feature set, which needs floor measures)."""
    with transaction(session_factory) as session:
        for robot_id, ward in (
            ("robot-a", "ward-a"),
            ("robot-b", "ward-a"),
            ("robot-c", "ward-a"),
            ("robot-d", "ward-b"),
        ):
            session.add(
                Robot(
                    id=robot_id,
                    name=robot_id,
                    ward=ward,
                    inputs=FEEDS_ALL,
                    token_hash=hash_robot_token(ROBOT_TOKEN),
                )
            )
    return ["robot-a", "robot-b", "robot-c", "robot-d"]
