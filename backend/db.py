"""Engine and session factory, built at start-up (never at import)."""

from __future__ import annotations

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.orm import Session, sessionmaker

from backend.models.base import Base
from backend.unit_of_work import transaction

__all__ = ["Base", "make_engine", "make_session_factory", "transaction"]


def make_engine(database_url: str, pool_size: int = 10, max_overflow: int = 20) -> Engine:
    """`pool_size`, `max_overflow`: PostgreSQL connections kept open, and opened beyond them
    for a peak (each closed again when returned: a new server process per checkout)."""
    if database_url.startswith("sqlite"):
        engine = create_engine(
            database_url, connect_args={"check_same_thread": False, "timeout": 30}
        )

        @event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_connection, _record) -> None:
            cursor = dbapi_connection.cursor()
            # Set only where they change something: on an existing file both need the lock a
            # stalled write holds, and a new connection (a request, a robot's hello) must not
            # wait on it (issue 32). auto_vacuum takes effect on a new file only (before its
            # first table; migration 0011 converts an existing one): retention gives freed
            # pages back chunk by chunk. WAL is kept by the file once set.
            if cursor.execute("PRAGMA page_count").fetchone()[0] == 0:
                cursor.execute("PRAGMA auto_vacuum=INCREMENTAL")
            if cursor.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
                cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.execute("PRAGMA foreign_keys=ON")
            cursor.close()

        return engine
    return create_engine(
        database_url, pool_size=pool_size, max_overflow=max_overflow, pool_pre_ping=True
    )


def make_session_factory(engine: Engine) -> sessionmaker[Session]:
    return sessionmaker(engine, expire_on_commit=False)
