"""The one transaction boundary (backend.unit_of_work): nothing else commits, and what is
registered on a unit runs only once it has committed."""

from __future__ import annotations

import ast
import asyncio
from pathlib import Path

import pytest
from sqlalchemy import select

from backend.models.robots import Robot
from backend.unit_of_work import UnitOfWork, after_commit, unit_of_work

ROOT = Path(__file__).resolve().parents[2]
BOUNDARY = Path("backend/unit_of_work.py")
#: Server code: the backend and the worker's jobs.
SCANNED = ("backend", "worker")
#: `.begin()` as a context manager commits too (Session.begin, Engine.begin).
COMMITTING_CALLS = {"commit", "begin", "begin_nested"}


def committing_calls(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in COMMITTING_CALLS
        ):
            found.append(f"{path.relative_to(ROOT)}:{node.lineno}: .{node.func.attr}(")
    return found


def test_only_the_unit_of_work_commits():
    offenders = []
    for package in SCANNED:
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.relative_to(ROOT) != BOUNDARY:
                offenders += committing_calls(path)
    assert not offenders, "commit outside backend/unit_of_work.py:\n" + "\n".join(offenders)
    assert committing_calls(ROOT / BOUNDARY), "the scan no longer sees the one commit"


class Recorder:
    def __init__(self) -> None:
        self.alarms: list[dict] = []
        self.robots: list[list[str]] = []

    async def publish_alarm(self, alarm: dict) -> None:
        self.alarms.append(alarm)

    async def push_assignments(self, robot_ids: list[str]) -> None:
        self.robots.append(robot_ids)


def test_effects_run_after_the_commit_and_never_after_a_rollback(session_factory):
    seen: list[str] = []
    with unit_of_work(session_factory) as unit:
        unit.session.add(Robot(id="robot-u", name="", ward="ward-a"))
        after_commit(unit.session, lambda: seen.append("closed"))
        unit.push_assignments(["robot-u", "robot-u"])
        assert seen == []
    with pytest.raises(RuntimeError), unit_of_work(session_factory) as failed:
        failed.session.add(Robot(id="robot-v", name="", ward="ward-a"))
        after_commit(failed.session, lambda: seen.append("never"))
        raise RuntimeError("refused")
    effects = Recorder()
    asyncio.run(unit.run_after_commit(effects))
    asyncio.run(failed.run_after_commit(effects))
    asyncio.run(unit.run_after_commit(effects))  # once only
    assert seen == ["closed"] and effects.robots == [["robot-u"]]
    with session_factory() as session:
        assert session.scalars(select(Robot.id)).all() == ["robot-u"]


def test_an_alarm_is_pushed_as_committed_once_per_unit(session_factory):
    from backend.alarms import service
    from backend.models.alarms import AlarmKind

    with unit_of_work(session_factory) as unit:
        robot = Robot(id="robot-u", name="", ward="ward-a")
        unit.session.add(robot)
        evidence = service.DecisionEvidence(seq=1, ts=0.0)
        alarm, new = service.raise_or_update(
            unit.session, robot, None, AlarmKind.EMERGENCY, evidence
        )
        service.raise_or_update(unit.session, robot, None, AlarmKind.EMERGENCY, evidence)
        service.publish(unit.session, alarm)
    effects = Recorder()
    asyncio.run(unit.run_after_commit(effects))
    assert new and [(a["id"], a["decision_count"]) for a in effects.alarms] == [(alarm.id, 2)]


def test_a_failing_effect_does_not_stop_the_others(session_factory):
    seen = []

    def broken() -> None:
        raise OSError("socket gone")

    unit = UnitOfWork(session_factory)
    unit.after_commit(broken)
    unit.after_commit(lambda: seen.append("second"))
    unit.commit()
    unit.close()
    asyncio.run(unit.run_after_commit(Recorder()))
    assert seen == ["second"]
