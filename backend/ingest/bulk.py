"""The one bulk insert of the ingest hot path: frame rows as tuples, straight to the driver.

SQLite: one `executemany` of a prepared INSERT. PostgreSQL: `COPY frames (...) FROM STDIN` in
binary format through psycopg (a third of the CPU of the text format on both sides: no hex
escaping of the blobs, no number formatting and parsing). Both run on the session's connection,
inside its transaction.
"""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy.orm import Session

# Column and the PostgreSQL type whose binary format COPY sends. The json columns get their
# text as "text": json's binary format is that text, while psycopg's json dumper would encode
# the Python str again, as a JSON string.
_FRAME_COLUMN_TYPES = (
    ("video_id", "int4"),
    ("index", "int4"),
    ("ts", "float8"),
    ("robot_id", "varchar"),
    ("seq", "int4"),
    ("keypoints", "bytea"),
    ("depth", "bytea"),
    ("floor", "bytea"),
    ("decision", "varchar"),
    ("scores", "text"),
    ("model_version", "varchar"),
    ("threshold", "float8"),
    ("delay_ms", "int4"),
    ("shadow_decision", "varchar"),
    ("shadow_scores", "text"),
    ("shadow_model_version", "varchar"),
)
FRAME_COLUMNS = tuple(column for column, _ in _FRAME_COLUMN_TYPES)
_PG_TYPES = [pg_type for _, pg_type in _FRAME_COLUMN_TYPES]
_QUOTED = ", ".join(f'"{c}"' for c in FRAME_COLUMNS)
_SQLITE_INSERT = f"INSERT INTO frames ({_QUOTED}) VALUES ({', '.join('?' for _ in FRAME_COLUMNS)})"
_PG_COPY = f"COPY frames ({_QUOTED}) FROM STDIN (FORMAT BINARY)"
_PG_TEXT_COPY = f"COPY frames ({_QUOTED}) FROM STDIN"
_INT4_COLUMNS = [i for i, pg_type in enumerate(_PG_TYPES) if pg_type == "int4"]
_INT4_MAX = 2**31 - 1


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
        binary = _fits_int4(rows)
        with (
            driver_connection.cursor() as cursor,
            cursor.copy(_PG_COPY if binary else _PG_TEXT_COPY) as copy,
        ):
            if binary:
                copy.set_types(_PG_TYPES)
            for row in rows:
                copy.write_row(row)
    else:  # pragma: no cover - only SQLite and PostgreSQL are supported
        raise NotImplementedError(f"bulk frame insert for {dialect}")


def _fits_int4(rows: Sequence[tuple]) -> bool:
    """Whether every integer fits its int4 column. psycopg's binary int4 dumper would silently
    keep the low 32 bits of a larger one (a robot may send any seq >= 0); text COPY lets
    PostgreSQL refuse it (DataError, the robot is told the value cannot be stored)."""
    return all(
        max((row[i] for row in rows if row[i] is not None), default=0) <= _INT4_MAX
        for i in _INT4_COLUMNS
    )
