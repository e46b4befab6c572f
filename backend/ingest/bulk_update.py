"""Many rows of one table updated by primary key, in one statement on PostgreSQL.

The writer's bookkeeping (robots.last_seq, videos.frame_count, transports.last_frame_at) changes
a row per robot per flush. An executemany sends one UPDATE per row (in pipeline mode, but still
one statement for the server to run and ~70 us of driver work each), which made this the largest
cost of a flush with 100 robots. PostgreSQL gets one `UPDATE ... FROM unnest(arrays)` instead;
SQLite, in process, keeps the executemany.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

from sqlalchemy import Table, bindparam, text, update
from sqlalchemy.dialects import postgresql
from sqlalchemy.orm import Session


def update_rows(
    session: Session, table: Table, columns: tuple[str, ...], rows: Sequence[tuple]
) -> None:
    """For each row: UPDATE table SET columns[1:] = row[1:] WHERE columns[0] = row[0]
    (the key values must be distinct)."""
    if not rows:
        return
    connection = session.connection()
    if connection.dialect.name == "postgresql":
        values = {f"c{i}": [row[i] for row in rows] for i in range(len(columns))}
        connection.execute(_unnest_update(table, columns), values)
    else:
        statement = (
            update(table)
            .where(table.c[columns[0]] == bindparam("c0"))
            .values({name: bindparam(f"c{i}") for i, name in enumerate(columns) if i})
        )
        connection.execute(
            statement, [{f"c{i}": value for i, value in enumerate(row)} for row in rows]
        )


@cache
def _unnest_update(table: Table, columns: tuple[str, ...]):
    dialect = postgresql.dialect()
    arrays = ", ".join(
        f"CAST(:c{i} AS {table.c[name].type.compile(dialect=dialect)}[])"
        for i, name in enumerate(columns)
    )
    names = ", ".join(f'"{name}"' for name in columns)
    assignments = ", ".join(f'"{name}" = v."{name}"' for name in columns[1:])
    key = columns[0]
    return text(
        f'UPDATE "{table.name}" AS t SET {assignments} FROM unnest({arrays}) AS v({names}) '
        f'WHERE t."{key}" = v."{key}"'
    )
