"""The jobs domain's reads (`backend.jobs.queries`) and its schemas (`backend.jobs.schemas`):
the list newest first, filtered by status and capped, one job by id; the routes that use them;
and the job schemas no longer living in the registry."""

from __future__ import annotations

import backend.registry.queries as registry_queries
import backend.registry.schemas as registry_schemas
from backend.db import transaction
from backend.jobs import queries, queue
from backend.jobs.schemas import JobDetail, JobOut
from backend.models.jobs import JobKind, JobStatus
from backend.models.users import Role


def _queue(session_factory, count: int) -> list[int]:
    with transaction(session_factory) as session:
        return [queue.enqueue(session, JobKind.WHATIF, {"n": i}).id for i in range(count)]


def test_list_jobs_is_newest_first_and_filters_by_status(session_factory):
    ids = _queue(session_factory, 3)
    with transaction(session_factory) as session:
        queue.request_cancel(session, queries.job_by_id(session, ids[1]))
    with session_factory() as session:
        assert [job.id for job in queries.list_jobs(session)] == ids[::-1]
        assert [job.id for job in queries.list_jobs(session, limit=2)] == ids[:0:-1]
        cancelled = queries.list_jobs(session, JobStatus.CANCELLED)
        assert [job.id for job in cancelled] == [ids[1]]
        queued = queries.list_jobs(session, JobStatus.QUEUED)
        assert [job.id for job in queued] == [ids[2], ids[0]]
        assert queries.list_jobs(session, JobStatus.RUNNING) == []


def test_list_jobs_caps_the_limit(session_factory):
    _queue(session_factory, queries.MAX_LIMIT + 3)
    with session_factory() as session:
        assert len(queries.list_jobs(session, limit=10_000)) == queries.MAX_LIMIT


def test_job_by_id(session_factory):
    (job_id,) = _queue(session_factory, 1)
    with session_factory() as session:
        job = queries.job_by_id(session, job_id)
        assert job is not None and job.id == job_id and job.params == {"n": 0}
        assert queries.job_by_id(session, job_id + 1) is None


def test_job_routes_read_through_the_jobs_domain(client, make_account, session_factory):
    engineer = make_account(Role.ENGINEER)
    ids = _queue(session_factory, 2)
    with transaction(session_factory) as session:
        queue.request_cancel(session, queries.job_by_id(session, ids[0]))
    listed = client.get("/api/jobs", headers=engineer.headers, params={"status": "cancelled"})
    assert listed.status_code == 200
    assert [JobOut.model_validate(j).id for j in listed.json()] == [ids[0]]
    one = client.get(f"/api/jobs/{ids[1]}", headers=engineer.headers)
    assert one.status_code == 200
    detail = JobDetail.model_validate(one.json())
    assert (detail.id, detail.status, detail.log) == (ids[1], JobStatus.QUEUED, "")
    missing = client.get(f"/api/jobs/{ids[1] + 100}", headers=engineer.headers)
    assert missing.status_code == 404
    assert missing.json()["detail"] == f"job {ids[1] + 100} not found"


def test_job_schemas_and_reads_are_the_jobs_domains():
    for name in ("JobIn", "JobOut", "JobDetail"):
        assert not hasattr(registry_schemas, name), f"{name} still in backend.registry.schemas"
    assert not hasattr(registry_queries, "list_jobs")
