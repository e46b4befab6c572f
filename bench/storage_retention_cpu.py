"""The CPU and wall time of one retention run, alone (no ingest), on a generated history: to
compare two versions of the retention code on identical databases.

    python -m bench.storage_retention_cpu load --database postgresql --frames 1000000
        creates a database (PostgreSQL: a template database; SQLite: a file) with
        bench.storage's generated history and prints its URL and `now`;
    python -m bench.storage_retention_cpu run --url URL --now NOW
        copies it (PostgreSQL: CREATE DATABASE ... TEMPLATE; SQLite: the file), runs
        `run_retention` of the code on PYTHONPATH on the copy, prints JSON: wall seconds, this
        process's CPU seconds, the PostgreSQL server's CPU seconds for its connections (from
        /proc, same machine) and the run's summary; then drops the copy.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
import uuid
from pathlib import Path

from sqlalchemy import create_engine, text

from backend.db import make_engine, make_session_factory
from backend.migrate import upgrade
from backend.storage.retention import run_retention
from backend.storage.settings import StorageSettings
from bench import storage

PG_ADMIN_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"


def _pg_server_cpu(admin, name: str) -> float:
    """CPU seconds (user + system) of the server processes connected to database `name`."""
    with admin.connect() as connection:
        pids = connection.execute(
            text("SELECT pid FROM pg_stat_activity WHERE datname = :n"), {"n": name}
        ).scalars()
        total = 0.0
        for pid in pids:
            try:
                fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def load(args) -> dict:
    now = time.time()
    if args.database == "postgresql":
        name = f"vigil_retention_cpu_{uuid.uuid4().hex[:8]}"
        admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}"'))
        admin.dispose()
        url = PG_ADMIN_URL.rsplit("/", 1)[0] + f"/{name}"
    else:
        url = f"sqlite:///{args.workdir / f'retention-cpu-{uuid.uuid4().hex[:8]}.db'}"
    upgrade(url)
    history = storage.load_history(url, args.frames, args.history_robots, args.days, now)
    return {"url": url, "now": now, "history": history, "disk": storage.disk(url)}


def run(args) -> dict:
    source = args.url
    if source.startswith("postgresql"):
        template = source.rsplit("/", 1)[1]
        name = f"{template}_c{uuid.uuid4().hex[:6]}"
        admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}" TEMPLATE "{template}"'))
        url = source.rsplit("/", 1)[0] + f"/{name}"
    else:
        path = Path(source.removeprefix("sqlite:///"))
        copy = path.with_name(f"{path.stem}-c{uuid.uuid4().hex[:6]}.db")
        shutil.copyfile(path, copy)
        url = f"sqlite:///{copy}"
    engine = make_engine(url)
    try:
        cpu, wall = time.process_time(), time.perf_counter()
        result = run_retention(make_session_factory(engine), StorageSettings(), now=args.now)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
        server = _pg_server_cpu(admin, name) if url.startswith("postgresql") else None
    finally:
        engine.dispose()
        if url.startswith("postgresql"):
            with admin.connect() as connection:
                connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
            admin.dispose()
        else:
            copy.unlink(missing_ok=True)
    return {
        "wall_seconds": round(wall, 2),
        "process_cpu_seconds": round(cpu, 2),
        "server_cpu_seconds": None if server is None else round(server, 2),
        "dropped_frames": result["dropped_frames"],
        "kept": result["kept"],
        "partitions": len(result["partitions_dropped"]),
        "disk_bytes_freed": result["disk_bytes_freed"],
        "load_average_1min": os.getloadavg()[0],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.storage_retention_cpu")
    sub = parser.add_subparsers(dest="command", required=True)
    loader = sub.add_parser("load")
    loader.add_argument("--database", choices=("postgresql", "sqlite"), default="postgresql")
    loader.add_argument("--frames", type=int, default=1_000_000)
    loader.add_argument("--history-robots", type=int, default=100)
    loader.add_argument("--days", type=float, default=40)
    loader.add_argument("--workdir", type=Path, default=Path("/tmp"))
    runner = sub.add_parser("run")
    runner.add_argument("--url", required=True)
    runner.add_argument("--now", type=float, required=True)
    args = parser.parse_args(argv)
    print(json.dumps(load(args) if args.command == "load" else run(args)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
