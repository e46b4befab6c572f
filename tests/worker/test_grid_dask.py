"""Grid search scale-out: GridSearchCV on a local Dask cluster (joblib's dask backend) ranks the
configurations exactly as the plain local run does, and the tasks really run on the cluster."""

from __future__ import annotations

import numpy as np
import pytest

from tests.registry_fixtures import SMALL_GRID
from worker.grid import GridBackend
from worker.training.cross_validation import select
from worker.training.data import from_urfd
from worker.training.estimators import ModelSpec
from worker.training.trainers import SklearnTrainer

NAMES = [f"fall-{i:02d}" for i in range(1, 5)] + [f"adl-{i:02d}" for i in range(1, 5)]


@pytest.fixture(scope="module")
def data():
    return from_urfd(names=NAMES)


def test_grid_search_on_a_local_dask_cluster_matches_the_local_run(data):
    from distributed import LocalCluster

    # Clearly different configurations, so float noise of threaded forests cannot flip the rank.
    grid = {**SMALL_GRID, "max_depth": [1, 16]}
    trainer = SklearnTrainer(ModelSpec("rf-grid", "rf", grid))
    sequences = np.arange(len(NAMES))
    local = select(trainer, data, sequences, n_inner=2)
    with LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp://",
        scheduler_port=0,
        dashboard_address=None,
    ) as cluster:
        with GridBackend(cluster.scheduler_address).active():
            on_dask = select(trainer, data, sequences, n_inner=2)
        executed = sum(w.state.executed_count for w in cluster.workers.values())
    assert cluster.scheduler_address.startswith("tcp://")
    assert executed >= 2  # both configurations ran on the cluster's worker
    assert [g["params"] for g in on_dask.grid_scores] == [g["params"] for g in local.grid_scores]
    assert [g["average_precision"] for g in on_dask.grid_scores] == pytest.approx(
        [g["average_precision"] for g in local.grid_scores],
        rel=1e-3,  # RF threads: float noise
    )
    assert on_dask.params == local.params
    assert on_dask.threshold == local.threshold and on_dask.delay_s == local.delay_s
