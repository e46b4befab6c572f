"""Which unstored Emergencies the storage watch pushes, and when (backend.ingest.failopen)."""

from __future__ import annotations

from backend.ingest.failopen import FailOpen
from backend.ingest.received import from_batch
from backend.ingest.writer import Job
from tests.backend.test_first_alarm import frame
from vigil.protocol import FrameBatch


class Link:
    def __init__(self, robot_id: str) -> None:
        self.robot_id = robot_id
        self.ward = "ward-a"


def emergency(robot_id: str, seq: int, at: float) -> Job:
    batch = from_batch(FrameBatch(frames=[frame(seq, "emergency", transport=f"t-{robot_id}")]))
    return Job(Link(robot_id), batch, at)


def no_one_waits() -> dict[str, str | None]:
    raise AssertionError("asked who waits while no write is blocked")


def test_each_unstored_emergency_is_pushed_once_when_due_and_a_stored_one_never():
    fail_open = FailOpen(unstored_alarm_s=0.3, stall_s=2.0)
    jobs = [emergency("r1", 1, 10.0), emergency("r2", 1, 10.1), emergency("r3", 1, 10.2)]
    for job in jobs:
        fail_open.on_submit(job)
    fail_open.on_submit(emergency("r1", 2, 10.25))  # same alarm as r1's first frame
    assert fail_open.due(10.29, no_one_waits) == []
    fail_open.on_write_done([jobs[1]])  # r2's frame committed in time
    pushed = fail_open.due(10.45, no_one_waits)
    assert [(a["robot_id"], a["decision_count"]) for a in pushed] == [("r1", 2)]
    assert fail_open.due(10.45, no_one_waits) == []  # once
    assert [a["robot_id"] for a in fail_open.due(10.6, no_one_waits)] == ["r3"]
    # r2 falls again after its first alarm was stored: a new entry, pushed when it is due.
    later = emergency("r2", 2, 11.0)
    fail_open.on_submit(later)
    assert fail_open.due(11.2, no_one_waits) == []
    assert [a["robot_id"] for a in fail_open.due(11.31, no_one_waits)] == ["r2"]
