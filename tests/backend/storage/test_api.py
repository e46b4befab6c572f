"""The admin's storage API and /metrics: figures per day and per robot, the next run, a dry
run queued as a worker job and run by it, archives made and imported again."""

from __future__ import annotations

from sqlalchemy import delete

from backend.db import transaction
from backend.models import Frame, Role
from backend.storage.policy import DAY_S
from tests.backend.storage import factories as f
from worker.jobs import retention
from worker.runner import Worker
from worker.settings import WorkerSettings


def test_storage_page_api_and_metrics(client, make_account, session_factory, settings, tmp_path):
    settings.archive_dir = tmp_path / "archive"
    old = f.CUTOFF_DAY - 2 * DAY_S + 3600
    with transaction(session_factory) as session:
        old_video = f.robot_video(session, "r1-old", "r1", [old + i for i in range(10)])
        f.robot_video(session, "r2-now", "r2", [f.NOW - i for i in range(5)], first_seq=50)
        old_id = old_video.id
    admin = make_account(Role.ADMIN, None)
    engineer = make_account(Role.ENGINEER, None)
    assert client.get("/api/storage/summary", headers=engineer.headers).status_code == 403

    page = client.get("/api/storage/summary", headers=admin.headers).json()
    assert page["total_frames"] == 15
    assert {r["robot_id"]: r["frames"] for r in page["robots"]} == {"r1": 10, "r2": 5}
    assert [d["frames"] for d in page["days"]] == [10, 5]
    assert page["days"][-1]["cumulative_frames"] == 15
    assert page["next_run"]["older_frames"] == 10 and page["next_run"]["preview"] is None

    job = client.post("/api/storage/retention", json={"dry_run": True}, headers=admin.headers)
    assert job.status_code == 201 and job.json()["kind"] == "retention"
    worker = Worker(
        WorkerSettings(database_url=settings.database_url),
        factory=session_factory,
        handlers={"retention": retention.run},
        sweeps=[],
    )
    assert worker.run_once() == job.json()["id"]
    done = client.get(f"/api/jobs/{job.json()['id']}", headers=admin.headers).json()
    assert done["status"] == "succeeded" and done["progress"] == 1.0
    page = client.get("/api/storage/summary?fresh=true", headers=admin.headers).json()
    assert page["next_run"]["preview"]["dropped_frames"] == 10
    assert page["total_frames"] == 15  # a dry run drops nothing

    made = client.post("/api/storage/archives", json={"video_id": old_id}, headers=admin.headers)
    assert made.status_code == 201, made.text
    archive_id = made.json()[0]["id"]
    with transaction(session_factory) as session:
        session.execute(delete(Frame).where(Frame.video_id == old_id))
    listed = client.get("/api/storage/archives", headers=engineer.headers).json()
    assert listed[0]["frames_in_database"] == 0 and listed[0]["frame_count"] == 10
    back = client.post(f"/api/storage/archives/{archive_id}/import", headers=engineer.headers)
    assert back.status_code == 200 and back.json()["frames_in_database"] == 10

    client.get("/api/storage/summary?fresh=true", headers=admin.headers)  # /metrics: cached
    metrics = client.get("/metrics", headers=admin.headers).text
    assert 'vigil_storage_frames{robot="r1"} 10.0' in metrics
    assert "vigil_retention_preview_drop_frames 10.0" in metrics
    assert "vigil_storage_archives 1.0" in metrics
