"""Shared fixtures. The database is chosen by VIGIL_TEST_DATABASE: `sqlite` (default) or
`postgresql` (a throwaway database on 127.0.0.1:5432 is created for the run and dropped)."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from backend.migrate import upgrade
from tests.support import shared_pool
from tests.support.shared_pool import DATABASE_FIXTURES, uses_database  # noqa: F401

PG_ADMIN_URL = os.environ.get(
    "VIGIL_TEST_PG_ADMIN_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)
KEEP_TABLES = {"alembic_version", "taxonomy_versions", "taxonomy_labels"}


def pytest_configure(config) -> None:
    # VIGIL_TEST_POOL: two runs side by side share out the database-independent tests.
    shared_pool.register(config)


def pytest_report_header(config) -> str:
    return f"vigil test database: {test_database_kind()}"


def test_database_kind() -> str:
    kind = os.environ.get("VIGIL_TEST_DATABASE", "sqlite")
    if kind not in ("sqlite", "postgresql"):
        raise pytest.UsageError(f"VIGIL_TEST_DATABASE must be sqlite or postgresql, not {kind!r}")
    return kind


def create_throwaway_database(name_hint: str = "vigil_test") -> tuple[str, callable]:
    """Create a PostgreSQL database; returns its URL and a function that drops it."""
    name = f"{name_hint}_{uuid.uuid4().hex[:10]}"
    admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))

    def drop() -> None:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()

    return PG_ADMIN_URL.rsplit("/", 1)[0] + f"/{name}", drop


@pytest.fixture(scope="session")
def migrated_database_url(tmp_path_factory) -> Iterator[str]:
    if test_database_kind() == "postgresql":
        url, drop = create_throwaway_database()
        upgrade(url)
        yield url
        drop()
    else:
        path: Path = tmp_path_factory.mktemp("db") / "vigil.db"
        url = f"sqlite:///{path}"
        upgrade(url)
        yield url


@pytest.fixture
def database_url(migrated_database_url: str) -> Iterator[str]:
    """A migrated database, emptied (but for the seeded taxonomy) after each test."""
    yield migrated_database_url
    engine = create_engine(migrated_database_url)
    with engine.begin() as connection:
        from backend import models  # noqa: F401
        from backend.db import Base

        for table in reversed(Base.metadata.sorted_tables):
            if table.name not in KEEP_TABLES:
                connection.execute(table.delete())
    engine.dispose()


def pytest_collection_modifyitems(config, items):
    """On the PostgreSQL run, keep only the tests that touch a database: the others (domain
    package, training, robot perception) do not depend on it and ran on the SQLite run."""
    if test_database_kind() != "postgresql":
        return
    keep, drop = [], []
    for item in items:
        (keep if uses_database(item) else drop).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep
