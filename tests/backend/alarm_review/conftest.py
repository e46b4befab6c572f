from __future__ import annotations

import pytest
from sqlalchemy.orm import Session

from backend.db import make_engine, make_session_factory


@pytest.fixture
def session(database_url: str) -> Session:
    engine = make_engine(database_url)
    with make_session_factory(engine)() as db:
        yield db
        db.rollback()
    engine.dispose()
