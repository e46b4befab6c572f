"""Many rows of one table updated by primary key, in one statement on PostgreSQL, and several
such statements sent in one round trip.

The writer's bookkeeping (robots.last_seq, videos.frame_count, transports.last_frame_at) changes
a row per robot per flush. An executemany sends one UPDATE per row (in pipeline mode, but still
one statement for the server to run and ~70 us of driver work each), which made this the largest
cost of a flush with 100 robots. PostgreSQL gets one `UPDATE ... FROM unnest(arrays)` instead;
SQLite, in process, keeps the executemany.

A flush writes back three tables; each statement waited for its answer before the next was
sent, and on a loaded machine every wait is a wake-up of the PostgreSQL backend and of the
writer thread (the GIL taken back from the event loop). `one_round_trip` sends them together
(psycopg's pipeline mode): they run in order, in the same transaction, and an error in any is
raised at the end of the block.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import cache

from sqlalchemy import Table, bindparam, func, update
from sqlalchemy.dialects import postgresql
from sqlalchemy.orm import Session


def update_rows(
    session: Session,
    table: Table,
    columns: tuple[str, ...],
    rows: Sequence[tuple],
    keep_stored_if_none: tuple[str, ...] = (),
) -> None:
    """For each row: UPDATE table SET columns[1:] = row[1:] WHERE columns[0] = row[0]
    (the key values must be distinct); a column named in `keep_stored_if_none` keeps its
    stored value where the row's is None."""
    if not rows:
        return
    connection = session.connection()
    if connection.dialect.name == "postgresql":
        values = {f"c{i}": [row[i] for row in rows] for i in range(len(columns))}
        connection.connection.driver_connection.execute(
            _unnest_update(table, columns, keep_stored_if_none), values
        )
    else:
        statement = (
            update(table)
            .where(table.c[columns[0]] == bindparam("c0"))
            .values(
                {
                    name: func.coalesce(bindparam(f"c{i}"), table.c[name])
                    if name in keep_stored_if_none
                    else bindparam(f"c{i}")
                    for i, name in enumerate(columns)
                    if i
                }
            )
        )
        connection.execute(
            statement, [{f"c{i}": value for i, value in enumerate(row)} for row in rows]
        )


@contextmanager
def one_round_trip(session: Session) -> Iterator[None]:
    """The `update_rows` inside go to PostgreSQL together and are answered together."""
    connection = session.connection()
    if connection.dialect.name != "postgresql":
        yield
        return
    with connection.connection.driver_connection.pipeline():
        yield


@cache
def _unnest_update(table: Table, columns: tuple[str, ...], keep_stored_if_none: tuple[str, ...]):
    """The statement in psycopg's own parameter style (it runs on the driver connection)."""
    dialect = postgresql.dialect()
    arrays = ", ".join(
        f"CAST(%(c{i})s AS {table.c[name].type.compile(dialect=dialect)}[])"
        for i, name in enumerate(columns)
    )
    names = ", ".join(f'"{name}"' for name in columns)
    assignments = ", ".join(
        f'"{name}" = COALESCE(v."{name}", t."{name}")'
        if name in keep_stored_if_none
        else f'"{name}" = v."{name}"'
        for name in columns[1:]
    )
    key = columns[0]
    return (
        f'UPDATE "{table.name}" AS t SET {assignments} FROM unnest({arrays}) AS v({names}) '
        f'WHERE t."{key}" = v."{key}"'
    )
