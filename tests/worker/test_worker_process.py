"""`vigil-worker run` as a real process: it runs a queued retrain job; killed mid-job (SIGKILL,
no goodbye), the job is taken over by another worker once its heartbeat is stale."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from backend.db import transaction
from backend.jobs import queue
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.registry import ModelVersion
from tests.registry_fixtures import SMALL_GRID
from worker.jobs import HANDLERS
from worker.runner import Worker

REPO = Path(__file__).resolve().parents[2]


def test_a_killed_worker_process_leaves_its_job_to_the_next_worker(
    factory, worker_settings, urfd_db, database_url, tmp_path
):
    with transaction(factory) as session:
        job_id = queue.enqueue(session, JobKind.RETRAIN, {"n_inner": 3, "grid": SMALL_GRID}).id
    # The successor takes retrain jobs only: the doomed worker's own sweeps queue the scheduled
    # retention run (backend.storage.sweeps), which is not what this test is about.
    retrain_only = {JobKind.RETRAIN: HANDLERS[JobKind.RETRAIN]}
    successor = Worker(
        worker_settings.model_copy(update={"worker_stale_after_s": 3.0}),
        factory,
        handlers=retrain_only,
        sweeps=[],
    )
    env = {
        **os.environ,
        "VIGIL_DATABASE_URL": database_url,
        "VIGIL_MODEL_STORE_DIR": str(worker_settings.model_store_dir),
        "VIGIL_WORKER_ID": "doomed",
        "VIGIL_WORKER_HEARTBEAT_S": "0.2",
    }
    process = subprocess.Popen(
        [sys.executable, "-m", "worker.cli", "run"],
        cwd=REPO,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # Generous: on a loaded 2-core machine, start-up and loading URFD took over a minute once.
        deadline = time.monotonic() + 180
        while True:  # wait until it is inside the grid search
            assert time.monotonic() < deadline, process.stderr.read() if process.poll() else ""
            with factory() as session:
                job = session.get(Job, job_id)
                if job.status == JobStatus.RUNNING and "grid search" in job.message:
                    break
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
        process.wait(10)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    with factory() as session:
        job = session.get(Job, job_id)
        assert (job.status, job.worker_id, job.attempts) == (JobStatus.RUNNING, "doomed", 1)

    assert successor.run_once() is None  # heartbeat still fresh: not taken yet
    time.sleep(3.2)
    assert successor.run_once() == job_id
    with factory() as session:
        job = session.get(Job, job_id)
        assert job.status == JobStatus.SUCCEEDED, job.log
        assert job.attempts == 2 and job.worker_id == "test-worker"
        assert "stopped sending heartbeats" in job.log
        assert session.get(ModelVersion, job.result["model_version_id"]) is not None
