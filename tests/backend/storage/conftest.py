from __future__ import annotations

from collections.abc import Iterator

import pytest

from backend.db import make_engine, make_session_factory
from backend.migrate import upgrade
from tests.conftest import create_throwaway_database


@pytest.fixture
def pg_factory() -> Iterator:
    """A session factory on a throwaway PostgreSQL database at head (frames partitioned)."""
    url, drop = create_throwaway_database("vigil_partitions")
    engine = None
    try:
        upgrade(url)
        engine = make_engine(url)
        yield make_session_factory(engine)
    finally:
        if engine is not None:
            engine.dispose()
        drop()
