"""Fixtures shared by the worker and registry tests: a few real URFD recordings in the database
(training and gold split) and one small model trained on URFD once per test session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from backend.db import make_engine, make_session_factory, transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models.videos import Split
from tests.support.model_cache import trained_once
from vigil.model_file import read_manifest, write_model
from worker.settings import WorkerSettings

TRAIN = [f"fall-{i:02d}" for i in range(1, 7)] + [f"adl-{i:02d}" for i in range(1, 7)]
GOLD = ["fall-07", "fall-08", "adl-07", "adl-08"]
SMALL_GRID = {
    "n_estimators": [30],
    "max_depth": [8, 16],
    "min_samples_leaf": [5],
    "max_features": [0.3],
}


@pytest.fixture
def factory(database_url: str):
    engine = make_engine(database_url)
    yield make_session_factory(engine)
    engine.dispose()


@pytest.fixture
def worker_settings(database_url: str, tmp_path: Path) -> WorkerSettings:
    return WorkerSettings(
        database_url=database_url,
        model_store_dir=tmp_path / "models",
        worker_id="test-worker",
        worker_heartbeat_s=0.2,
        worker_poll_s=0.05,
        worker_sweep_s=0.0,
    )


@pytest.fixture
def urfd_db(factory) -> None:
    with transaction(factory) as session:
        import_urfd(session, names=TRAIN, split=Split.TRAIN)
        import_urfd(session, names=GOLD, split=Split.TEST)


@pytest.fixture(scope="session")
def trained_model_dir(tmp_path_factory) -> Path:
    """A random forest trained on the URFD training recordings (detection code's own path)."""
    from worker.training.cross_validation import select
    from worker.training.data import from_urfd
    from worker.training.estimators import ModelSpec
    from worker.training.publish import publish
    from worker.training.trainers import SklearnTrainer

    def train(out: Path) -> None:
        data = from_urfd(names=TRAIN)
        grid = {k: v[:1] for k, v in SMALL_GRID.items()}
        trainer = SklearnTrainer(ModelSpec("rf-test", "rf", grid))
        selected = select(trainer, data, np.arange(len(data.names)), n_inner=3, stride=2)
        publish(trainer, selected, data, out, version="rf-test-1")

    return trained_once("rf-test", train, tmp_path_factory.mktemp("model") / "rf-test")


def derive_model(source: Path, out: Path, version: str, **changes) -> Path:
    """The same ONNX graph under another version and operating point (e.g. threshold 1.0)."""
    manifest, directory = read_manifest(source)
    onnx_bytes = (directory / manifest.file).read_bytes()
    if "training_recordings" in changes:  # kept in the metrics (ModelManifest.training_recordings)
        changes["metrics"] = {
            **manifest.metrics,
            "training_recordings": changes.pop("training_recordings"),
        }
    write_model(out, onnx_bytes, manifest.model_copy(update={"version": version, **changes}))
    return out


def second_version(source: Path, out: Path, threshold: float) -> Path:
    """`rf-test-2`: the same graph at another threshold, with a 400 ms delay. The small test
    model chooses its delay on 12 recordings (a long one with feature version 5), so at a higher
    threshold its gold-set falls alarm only just before they end; the shorter delay keeps the
    version a clear pass of the promotion gate, which these tests need in order to exercise
    rollout and rollback."""
    return derive_model(source, out, "rf-test-2", threshold=threshold, delay_ms=400)
