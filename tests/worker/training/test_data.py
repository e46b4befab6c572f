"""Train equals serve (issue #34): one URFD recording through the robot's pipeline and through the
one builder of training rows, from the URFD files and from the database, gives the same feature
rows. fall-01 carries the 11 real depth pictures, so depth, floor and keypoints all count."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select

from backend.db import transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models.videos import Video
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.sources.replay import UrfdReplaySource
from vigil.classes import Decision, TransportMode
from vigil.datasets import urfd
from vigil.features import FEATURE_NAMES, FEATURE_VERSION
from vigil.model_file import ModelManifest
from vigil.runtime import FrameClassifier
from worker.db_data import frame_data
from worker.training.data import from_urfd

URFD_DIR = urfd.default_dir()
NAMES = ["fall-01", "adl-01"]


class FeatureRecorder:
    """A model that keeps the feature rows it is given (and always says Normal)."""

    def __init__(self) -> None:
        self.manifest = ModelManifest(
            version="feature-recorder",
            mode=TransportMode.WALKING,
            classes=[Decision.NORMAL, Decision.EMERGENCY],
            feature_version=FEATURE_VERSION,
            feature_set="full",
            taxonomy_version=1,
            threshold=0.5,
            delay_ms=0,
            training_data_sha256="0" * 64,
            sha256="0" * 64,
        )
        self.sha256 = "0" * 64
        self.rows: list[np.ndarray] = []

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        self.rows.append(np.array(features[0], np.float32))
        return np.array([[0.9, 0.1]], np.float32)


def robot_rows(name: str, workdir: Path) -> np.ndarray:
    """The recording as a robot replays it (depth pictures included) through robot_agent's
    Pipeline: the feature rows its model is handed."""
    recorder = FeatureRecorder()
    pipeline = Pipeline(
        Outbox(workdir / f"{name}.sqlite"), TransportMode.WALKING, FrameClassifier(recorder)
    )
    pipeline.start_transport(f"t-{name}", time.time())
    source = UrfdReplaySource(name, URFD_DIR, speed=0, depth_dir=URFD_DIR / urfd.DEPTH_DIR)
    for observation in source:
        pipeline.process(observation)
    return np.stack(recorder.rows)


def differing_columns(a: np.ndarray, b: np.ndarray) -> list[str]:
    assert a.shape == b.shape
    same = np.isclose(a, b, rtol=0, atol=1e-6, equal_nan=True)
    return [FEATURE_NAMES[c] for c in np.flatnonzero(~same.all(axis=0))]


@pytest.fixture
def database_rows(factory):
    with transaction(factory) as session:
        import_urfd(session, URFD_DIR, NAMES)
    with factory() as session:
        videos = list(session.scalars(select(Video).where(Video.name.in_(NAMES))))
        videos.sort(key=lambda v: NAMES.index(v.name))
        return frame_data(session, videos, TransportMode.WALKING)


def test_robot_file_and_database_give_identical_feature_rows(database_rows, tmp_path):
    files = from_urfd(URFD_DIR, NAMES)
    assert database_rows.names == files.names == NAMES
    for k, name in enumerate(NAMES):
        robot = robot_rows(name, tmp_path)
        from_files = files.features[files.group == k]
        from_database = database_rows.features[database_rows.group == k]
        assert (
            len(robot) == len(from_files) == len(from_database) == len(urfd.load(None, [name])[0])
        )
        assert differing_columns(robot, from_files) == [], name
        assert differing_columns(robot, from_database) == [], name
    np.testing.assert_array_equal(files.target, database_rows.target)
    np.testing.assert_array_equal(files.usable, database_rows.usable)
    np.testing.assert_allclose(files.timestamps, database_rows.timestamps, atol=1e-6)
    # fall-01's depth pictures reach the rows: the test would pass vacuously without them
    has_depth = FEATURE_NAMES.index("has_depth")
    assert int((files.features[files.group == 0, has_depth] > 0).sum()) == 11
