"""Rows updated by key in bulk (one statement on PostgreSQL, executemany on SQLite)."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import select

from backend.db import transaction
from backend.ingest.bulk_update import one_round_trip, update_rows
from backend.models.robots import Robot


def robot_rows(session_factory) -> list[tuple]:
    with session_factory() as session:
        rows = session.execute(
            select(
                Robot.id, Robot.last_seq, Robot.last_seen_at, Robot.running_model_version
            ).order_by(Robot.id)
        ).all()
    return [tuple(row) for row in rows]


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
    assert robot_rows(session_factory) == [
        ("r1", 41, seen, None),
        ("r2", 1, None, "m-7"),
        ("r3", None, seen + timedelta(seconds=2), None),
    ]


def test_a_column_kept_where_the_row_says_none_and_statements_sent_together(session_factory):
    """transports.last_patient_at is written only by flushes that saw the patient; the three
    tables' updates of a flush go in one round trip (PostgreSQL's pipeline mode) and each
    still sees its own rows."""
    seen = datetime(2026, 11, 22, 3, 0, tzinfo=UTC)
    with transaction(session_factory) as session:
        for name in ("r1", "r2"):
            session.add(Robot(id=name, ward="w", last_seq=1, last_seen_at=seen))
    later = seen + timedelta(seconds=5)
    with transaction(session_factory) as session, one_round_trip(session):
        update_rows(
            session,
            Robot.__table__,
            ("id", "last_seq", "last_seen_at"),
            [("r1", 7, None), ("r2", 9, later)],
            keep_stored_if_none=("last_seen_at",),
        )
        update_rows(session, Robot.__table__, ("id", "running_model_version"), [("r1", "m")])
    assert robot_rows(session_factory) == [("r1", 7, seen, "m"), ("r2", 9, later, None)]


def test_an_error_inside_one_round_trip_fails_the_flush(session_factory):
    with transaction(session_factory) as session:
        session.add(Robot(id="r1", ward="w"))
    # SQLAlchemy's IntegrityError on SQLite, the driver's own on PostgreSQL (as from COPY)
    refused = pytest.raises(Exception, match="(?i)not[ -]null")
    with refused, transaction(session_factory) as session, one_round_trip(session):
        update_rows(session, Robot.__table__, ("id", "ward"), [("r1", None)])  # NOT NULL
    with session_factory() as session:
        assert session.scalar(select(Robot.ward).where(Robot.id == "r1")) == "w"
