"""A register job reads only from the model store: any other path on the worker's host is
refused when the job is queued (422 naming `path`), and by the worker for a user's job."""

from __future__ import annotations

import shutil

import pytest

from backend.db import transaction
from backend.jobs import queue
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.users import Role, User
from worker.runner import Worker


@pytest.mark.parametrize(
    "path", ["/etc", "../../../../etc", "models-not/../../etc/passwd", "/", ".", "link-to-etc"]
)
def test_register_path_outside_the_model_store_is_refused(
    client, make_account, settings, session_factory, path
):
    store = settings.model_store_dir
    store.mkdir(parents=True, exist_ok=True)
    (store / "link-to-etc").symlink_to("/etc")
    engineer = make_account(Role.ENGINEER)
    response = client.post(
        "/api/jobs", headers=engineer.headers, json={"kind": "register", "params": {"path": path}}
    )
    assert response.status_code == 422
    detail = response.json()["detail"]
    assert detail.startswith("invalid job parameter path:") and "model store" in detail
    with session_factory() as session:
        assert session.query(Job).count() == 0  # nothing queued


def test_register_path_inside_the_model_store_is_queued(client, make_account, settings):
    engineer = make_account(Role.ENGINEER)
    for path in (str(settings.model_store_dir / "incoming" / "rf-1"), "incoming/rf-2"):
        response = client.post(
            "/api/jobs",
            headers=engineer.headers,
            json={"kind": "register", "params": {"path": path}},
        )
        assert response.status_code == 201, response.text
        assert response.json()["params"] == {"path": path}


def test_worker_refuses_a_users_register_job_outside_the_store(
    factory, worker_settings, urfd_db, trained_model_dir
):
    """A job queued before the API checked (or written to the queue directly) is refused too."""
    with transaction(factory) as session:
        user = User(username="eng", password_hash="x", role=Role.ENGINEER)
        session.add(user)
        session.flush()
        user_id = user.id
    with transaction(factory) as session:
        job_id = queue.enqueue(
            session, JobKind.REGISTER, {"path": str(trained_model_dir)}, user_id
        ).id
    assert Worker(worker_settings, factory, sweeps=[]).run_once() == job_id
    with factory() as session:
        job = session.get(Job, job_id)
        assert job.status == JobStatus.FAILED and "invalid job parameter path" in job.message
    # The same directory copied into the store registers.
    inside = worker_settings.model_store_dir / "incoming" / "rf-test"
    shutil.copytree(trained_model_dir, inside)
    with transaction(factory) as session:
        job_id = queue.enqueue(session, JobKind.REGISTER, {"path": "incoming/rf-test"}, user_id).id
    Worker(worker_settings, factory, sweeps=[]).run_once()
    with factory() as session:
        job = session.get(Job, job_id)
        assert job.status == JobStatus.SUCCEEDED, job.log
