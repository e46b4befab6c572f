"""The one bulk insert of the ingest hot path: frame rows as tuples, straight to the driver.

SQLite: one `executemany` of a prepared INSERT. PostgreSQL: `COPY frames (...) FROM STDIN`
through psycopg. Both run on the session's connection, inside its transaction.
"""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy.orm import Session

FRAME_COLUMNS = (
    "video_id", "index", "ts", "robot_id", "seq", "keypoints", "depth", "decision", "scores",
    "model_version", "threshold", "delay_ms", "shadow_decision", "shadow_scores",
    "shadow_model_version",
)  # fmt: skip
_QUOTED = ", ".join(f'"{c}"' for c in FRAME_COLUMNS)
_SQLITE_INSERT = f"INSERT INTO frames ({_QUOTED}) VALUES ({', '.join('?' for _ in FRAME_COLUMNS)})"
_PG_COPY = f"COPY frames ({_QUOTED}) FROM STDIN"


def insert_frame_rows(session: Session, rows: Sequence[tuple]) -> None:
    """Insert rows laid out as FRAME_COLUMNS (scores as JSON text, blobs as bytes)."""
    if not rows:
        return
    connection = session.connection()
    dialect = connection.dialect.name
    driver_connection = connection.connection.driver_connection
    if dialect == "sqlite":
        driver_connection.executemany(_SQLITE_INSERT, rows)
    elif dialect == "postgresql":
        with driver_connection.cursor() as cursor, cursor.copy(_PG_COPY) as copy:
            for row in rows:
                copy.write_row(row)
    else:  # pragma: no cover - only SQLite and PostgreSQL are supported
        raise NotImplementedError(f"bulk frame insert for {dialect}")
