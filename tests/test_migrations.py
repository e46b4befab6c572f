"""Migrations on the test database kind (throwaway database): upgrade from empty to head
matches the models, downgrade goes back to empty, and 0002 can be undone and redone."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect

from backend import models  # noqa: F401  (registers every table)
from backend.db import Base, make_engine
from backend.migrate import downgrade, upgrade
from backend.storage import partitions
from tests.conftest import create_throwaway_database
from tests.conftest import test_database_kind as database_kind


@pytest.fixture
def empty_database_url(tmp_path) -> Iterator[str]:
    if database_kind() == "postgresql":
        url, drop = create_throwaway_database("vigil_migrations")
        yield url
        drop()
    else:
        yield f"sqlite:///{tmp_path / 'migrations.db'}"


def tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names())
    finally:
        engine.dispose()


def schema_differences(url: str) -> list:
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            opts = {"compare_type": False}
            if connection.dialect.name == "postgresql":
                opts["include_object"] = partitions.include_object  # frames: day partitions
            context = MigrationContext.configure(connection, opts=opts)
            return compare_metadata(context, Base.metadata)
    finally:
        engine.dispose()


def transport_columns(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return {c["name"] for c in inspect(engine).get_columns("transports")}
    finally:
        engine.dispose()


def test_upgrade_from_empty_matches_the_models_and_downgrade_returns_to_empty(
    empty_database_url,
):
    url = empty_database_url
    assert tables(url) == set()
    upgrade(url)
    assert set(Base.metadata.tables) <= tables(url)
    assert schema_differences(url) == []

    downgrade(url, "0001")
    assert "last_frame_at" not in transport_columns(url)
    upgrade(url)
    assert "last_frame_at" in transport_columns(url)
    assert schema_differences(url) == []

    downgrade(url, "base")
    assert tables(url) <= {"alembic_version"}
