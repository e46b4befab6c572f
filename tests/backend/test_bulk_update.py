"""Rows updated by key in bulk (one statement on PostgreSQL, executemany on SQLite)."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from sqlalchemy import select

from backend.db import transaction
from backend.ingest.bulk_update import update_rows
from backend.models.robots import Robot


def test_each_row_gets_its_own_values_and_others_are_untouched(session_factory):
    seen = datetime(2026, 11, 22, 3, 0, tzinfo=UTC)
    with transaction(session_factory) as session:
        for name in ("r1", "r2", "r3"):
            session.add(Robot(id=name, ward="w", last_seq=1))
    with transaction(session_factory) as session:
        update_rows(
            session,
            Robot.__table__,
            ("id", "last_seq", "last_seen_at"),
            [("r1", 41, seen), ("r3", None, seen + timedelta(seconds=2))],
        )
        update_rows(session, Robot.__table__, ("id", "running_model_version"), [("r2", "m-7")])
        update_rows(session, Robot.__table__, ("id", "last_seq"), [])
    with session_factory() as session:
        rows = session.execute(
            select(
                Robot.id, Robot.last_seq, Robot.last_seen_at, Robot.running_model_version
            ).order_by(Robot.id)
        ).all()
    assert [tuple(row) for row in rows] == [
        ("r1", 41, seen, None),
        ("r2", 1, None, "m-7"),
        ("r3", None, seen + timedelta(seconds=2), None),
    ]
