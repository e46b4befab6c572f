"""The database job queue: claim, heartbeat, cancel, takeover of dead workers, and concurrent
claims by two workers (FOR UPDATE SKIP LOCKED on PostgreSQL) never taking one job twice."""

from __future__ import annotations

import threading
import time
from datetime import timedelta

import pytest
from sqlalchemy import select

from backend.db import make_engine, make_session_factory, transaction
from backend.jobs import queue
from backend.models._types import utcnow
from backend.models.jobs import Job, JobKind, JobStatus
from worker.context import JobContext
from worker.runner import Worker


def _enqueue(factory, n=1, kind=JobKind.EVALUATE, params=None) -> list[int]:
    with transaction(factory) as session:
        return [queue.enqueue(session, kind, params or {"i": i}).id for i in range(n)]


def test_claim_takes_the_oldest_job_once_and_records_the_outcome(factory):
    first, second = _enqueue(factory, 2)
    claim = queue.claim(factory, "w1")
    assert claim.id == first and claim.attempts == 1
    assert queue.claim(factory, "w2").id == second
    assert queue.claim(factory, "w3") is None  # both running with fresh heartbeats
    assert queue.report(factory, first, "w1", 0.5, "half way", ["a line"]) is False
    assert queue.report(factory, first, "intruder", 0.9) is None  # not its job
    assert queue.finish(factory, first, "w1", JobStatus.SUCCEEDED, "done", {"x": 1})
    with factory() as session:
        job = session.get(Job, first)
        assert (job.status, job.progress, job.result, job.worker_id) == (
            JobStatus.SUCCEEDED,
            1.0,
            {"x": 1},
            "w1",
        )
        assert "a line" in job.log and "succeeded: done" in job.log
        assert job.finished_at is not None
    with pytest.raises(queue.JobStateError), transaction(factory) as session:
        queue.request_cancel(session, session.get(Job, first))


def test_a_job_whose_worker_died_is_taken_over_and_fails_after_max_attempts(factory):
    (job_id,) = _enqueue(factory)
    assert queue.claim(factory, "dead-worker").id == job_id
    assert queue.claim(factory, "w2", stale_after_s=30) is None
    with transaction(factory) as session:  # the dead worker's last heartbeat was long ago
        session.get(Job, job_id).heartbeat_at = utcnow() - timedelta(minutes=5)
    claim = queue.claim(factory, "w2", stale_after_s=30)
    assert claim.id == job_id and claim.attempts == 2
    # The dead worker coming back finds the job is no longer its own.
    assert queue.report(factory, job_id, "dead-worker", 0.3) is None
    assert not queue.finish(factory, job_id, "dead-worker", JobStatus.SUCCEEDED, "late")
    with factory() as session:
        job = session.get(Job, job_id)
        assert job.worker_id == "w2" and "stopped sending heartbeats" in job.log
    with transaction(factory) as session:
        session.get(Job, job_id).heartbeat_at = utcnow() - timedelta(minutes=5)
    assert queue.claim(factory, "w3", stale_after_s=30, max_attempts=2) is None
    with factory() as session:
        job = session.get(Job, job_id)
        assert job.status == JobStatus.FAILED and "gave up after 2 attempts" in job.message


def test_cancel_queued_is_immediate_and_running_stops_at_next_progress(factory, worker_settings):
    queued, running = _enqueue(factory, 2)
    with transaction(factory) as session:
        queue.request_cancel(session, session.get(Job, queued))
    started = threading.Event()

    def slow_handler(context: JobContext) -> dict:
        for i in range(200):
            started.set()
            context.progress(i / 200, f"step {i}")
            time.sleep(0.02)
        return {"summary": "finished anyway"}

    worker = Worker(worker_settings, factory, handlers={JobKind.EVALUATE: slow_handler}, sweeps=[])
    thread = threading.Thread(target=worker.run_once)
    thread.start()
    assert started.wait(10)
    with transaction(factory) as session:
        queue.request_cancel(session, session.get(Job, running))
    thread.join(20)
    with factory() as session:
        assert session.get(Job, queued).status == JobStatus.CANCELLED
        job = session.get(Job, running)
        assert job.status == JobStatus.CANCELLED, job.message
        assert job.progress < 1.0 and "step" in job.log


def test_a_failing_job_is_recorded_with_its_error_and_the_worker_goes_on(factory, worker_settings):
    bad, good = _enqueue(factory, 2)

    def handler(context: JobContext) -> dict:
        if context.job_id == bad:
            raise ValueError("invalid job parameter model_version_id: model 99 not found")
        return {"summary": "fine"}

    worker = Worker(worker_settings, factory, handlers={JobKind.EVALUATE: handler}, sweeps=[])
    assert worker.run_once() == bad
    assert worker.run_once() == good
    with factory() as session:
        failed = session.get(Job, bad)
        assert failed.status == JobStatus.FAILED
        assert "model_version_id" in failed.message and "Traceback" in failed.log
        assert session.get(Job, good).status == JobStatus.SUCCEEDED


def test_two_concurrent_workers_never_claim_the_same_job(database_url):
    """Two workers with their own connections race for 30 jobs (SKIP LOCKED on PostgreSQL)."""
    engines = [make_engine(database_url) for _ in range(3)]
    factories = [make_session_factory(e) for e in engines]
    ids = set(_enqueue(factories[2], 30))
    claims: dict[str, list[int]] = {"a": [], "b": []}
    barrier = threading.Barrier(2)

    def work(name: str, factory) -> None:
        barrier.wait()
        while (claim := queue.claim(factory, name)) is not None:
            claims[name].append(claim.id)
            queue.finish(factory, claim.id, name, JobStatus.SUCCEEDED, "ok")

    threads = [
        threading.Thread(target=work, args=(n, f)) for n, f in zip("ab", factories[:2], strict=True)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    taken = claims["a"] + claims["b"]
    assert sorted(taken) == sorted(ids)  # every job exactly once
    with factories[2]() as session:
        jobs = session.scalars(select(Job)).all()
        assert all(j.status == JobStatus.SUCCEEDED and j.attempts == 1 for j in jobs)
        assert {j.worker_id for j in jobs} <= {"a", "b"}
    for engine in engines:
        engine.dispose()


def test_the_claim_query_skips_locked_rows_on_postgresql():
    from sqlalchemy.dialects import postgresql, sqlite

    query = queue.claim_query("postgresql", utcnow(), 30)
    assert "FOR UPDATE SKIP LOCKED" in str(query.compile(dialect=postgresql.dialect()))
    assert "FOR UPDATE" not in str(
        queue.claim_query("sqlite", utcnow(), 30).compile(dialect=sqlite.dialect())
    )
