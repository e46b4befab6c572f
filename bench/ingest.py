"""`make bench-ingest`: the real backend (uvicorn subprocess) and N simulated robots over
loopback websockets, on SQLite and on PostgreSQL. Writes bench/results/ingest.json.

Frames are GENERATED (a fixed skeleton with a moving sequence number): this measures the
ingest path, not detection quality. Per run:
- frames_per_s: frames acknowledged (= committed) per second over the measurement window;
- ack latency: robot sends a frame -> receives an ack covering its sequence number;
- alarm latency: robot sends an Emergency frame -> a nurse websocket receives the alarm whose
  last_seq covers it;
- frames_lost: frames sent but not in the database after the run; duplicates: rows beyond one per
  (robot, seq). Each robot also re-sends its first batch at the end (a reconnect replay), which
  must not create duplicates.

Like the real agent (robot_agent/outbox.py), each robot numbers its frames after the welcome's
last_seq (from 0 on an empty database), so a run over a database an earlier run already wrote
to (bench.storage) sends new sequence numbers: the backend acknowledges a number it already has
but neither stores nor alarms on it. frames_lost and duplicates count only the sequence numbers
this run sent.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import platform
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sqlalchemy import create_engine, text
from sqlalchemy.exc import DBAPIError
from websockets.asyncio.client import connect

from backend.db import make_engine, make_session_factory, transaction
from backend.ingest.context import TRAILING_PUSH_GRACE_S, UPDATE_PUSH_S
from backend.migrate import upgrade
from backend.models.robots import Robot
from backend.models.users import Role, User
from backend.process import BackendProcess
from backend.security import create_access_token, hash_password, hash_robot_token

RESULTS = Path(__file__).resolve().parent / "results" / "ingest.json"
PG_ADMIN_URL = os.environ.get(
    "VIGIL_TEST_PG_ADMIN_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)
SECRET = "bench-secret"
REDIS_URL = os.environ.get("VIGIL_BENCH_REDIS_URL", "redis://127.0.0.1:6379/0")
WARD = "ward-bench"

_KEYPOINTS = json.dumps([[320.0 + i, 240.0 + 2 * i, 0.87] for i in range(25)])
_DEPTH = json.dumps([2.5] * 23 + [None, None])
_FRAME = (
    '{"seq":%d,"ts":%.4f,"transport_id":"%s","keypoints":'
    + _KEYPOINTS
    + ',"depth":'
    + _DEPTH
    + ',"decision":"%s","scores":{"normal":0.2,"emergency":0.8},"model_version":"bench-1",'
    '"threshold":0.5,"delay_ms":300}'
)


@dataclass
class RobotStats:
    robot_id: str
    first_seq: int = 0  # the welcome's last_seq + 1: this run's frames are first_seq and up
    sent_at: dict[int, float] = field(default_factory=dict)
    emergency_at: dict[int, float] = field(default_factory=dict)
    ack_latency_ms: list[tuple[float, float]] = field(default_factory=list)  # (sent at, ms)
    ack_times: list[tuple[float, int]] = field(default_factory=list)  # (time, frames newly acked)
    highest_ack: int = -1
    unacked: list[int] = field(default_factory=list)  # seqs sent and not yet acked, ascending
    acked: asyncio.Event = field(default_factory=asyncio.Event)


@dataclass
class RunConfig:
    database: str
    robots: int
    hz: float  # batches per second per robot (0: as fast as the ack window allows)
    batch: int  # frames per message
    seconds: float
    window: int  # most unacknowledged frames per robot
    emergency_every: int  # every n-th frame is an Emergency decision
    workers: int = 1  # uvicorn worker processes (>1: alarms fan out through Redis)


async def robot_client(
    url: str,
    robot_id: str,
    token: str,
    config: RunConfig,
    stop: asyncio.Event,
    stats: RobotStats,
) -> None:
    async with connect(url + "/ws/robot", max_size=None, compression=None) as ws:
        await ws.send(json.dumps({"type": "hello", "robot_id": robot_id, "token": token}))
        welcome = json.loads(await ws.recv())
        if welcome.get("type") != "welcome":
            raise RuntimeError(f"{robot_id}: expected a welcome, got {welcome!r:.200}")
        # Number after what the backend already has, as the agent does: a number at or below
        # last_seq would be acknowledged as a duplicate and dropped (no row, no alarm).
        last_seq = welcome["last_seq"]
        stats.first_seq = 0 if last_seq is None else last_seq + 1
        transport = f"{robot_id}-t"
        await ws.send(
            json.dumps(
                {
                    "type": "transport_start",
                    "transport_id": transport,
                    "mode": "walking",
                    "patient": "P-gen",
                    "location": "bench",
                    "ts": time.time(),
                }
            )
        )

        async def receive() -> None:
            async for raw in ws:
                message = json.loads(raw)
                if message.get("type") != "ack":
                    continue
                now = time.perf_counter()
                seq = message["seq"]
                covered = 0
                while stats.unacked and stats.unacked[0] <= seq:
                    s = stats.unacked.pop(0)
                    sent = stats.sent_at[s]
                    stats.ack_latency_ms.append((sent, (now - sent) * 1000))
                    covered += 1
                stats.highest_ack = max(stats.highest_ack, seq)
                stats.ack_times.append((now, covered))
                stats.acked.set()

        receiver = asyncio.create_task(receive())
        seq = stats.first_seq
        offset = int(robot_id.rsplit("-", 1)[1]) * 7
        period = 1 / config.hz if config.hz else 0
        next_at = time.perf_counter()
        first_batch = None
        while not stop.is_set():
            while len(stats.unacked) + config.batch > config.window:
                stats.acked.clear()
                try:
                    await asyncio.wait_for(stats.acked.wait(), 1)
                except TimeoutError:
                    if stop.is_set():
                        break
                if stop.is_set():
                    break
            if stop.is_set():
                break
            frames = []
            now = time.perf_counter()
            for _ in range(config.batch):
                # Staggered per robot, so the robots do not all raise alarms at the same moment.
                emergency = config.emergency_every and (seq + offset) % config.emergency_every == 0
                frames.append(
                    _FRAME % (seq, time.time(), transport, "emergency" if emergency else "normal")
                )
                stats.sent_at[seq] = now
                stats.unacked.append(seq)
                if emergency:
                    stats.emergency_at[seq] = now
                seq += 1
            message = '{"type":"frames","frames":[' + ",".join(frames) + "]}"
            first_batch = first_batch or message
            await ws.send(message)
            if period:
                next_at += period
                delay = next_at - time.perf_counter()
                if delay > 0:
                    await asyncio.sleep(delay)
                else:
                    next_at = time.perf_counter()
            else:
                await asyncio.sleep(0)
        # Drain: wait for every frame to be acknowledged, then replay this run's first batch.
        deadline = time.perf_counter() + 15
        while stats.unacked and time.perf_counter() < deadline:
            stats.acked.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stats.acked.wait(), 1)
        if first_batch:
            await ws.send(first_batch)
            await asyncio.sleep(0.3)
        receiver.cancel()


async def nurse_client(
    url: str, token: str, alarms: dict[str, list[tuple[float, int]]], ready: asyncio.Event
) -> None:
    async with connect(
        f"{url}/ws/browser",
        additional_headers={"Authorization": f"Bearer {token}"},
        max_size=None,
    ) as ws:
        json.loads(await ws.recv())  # snapshot
        ready.set()
        async for raw in ws:
            message = json.loads(raw)
            if message.get("type") == "alarm":
                alarm = message["alarm"]
                if alarm["last_seq"] is not None:
                    alarms.setdefault(alarm["robot_id"], []).append(
                        (time.perf_counter(), alarm["last_seq"])
                    )


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _histogram(server: BackendProcess, name: str) -> tuple[float, float] | None:
    """p50 and p99 of a Prometheus histogram of the backend, as bucket upper bounds in ms."""
    import urllib.request

    token = create_access_token(SECRET, 2, 60)
    request = urllib.request.Request(
        f"{server.http}/metrics", headers={"Authorization": f"Bearer {token}"}
    )
    with urllib.request.urlopen(request, timeout=10) as response:
        text = response.read().decode()
    buckets = []
    for line in text.splitlines():
        if line.startswith(f"{name}_bucket"):
            bound = line.split('le="')[1].split('"')[0]
            buckets.append((float(bound), float(line.rsplit(" ", 1)[1])))
    if not buckets or buckets[-1][1] == 0:
        return None
    total = buckets[-1][1]

    def quantile(q: float) -> float:
        return next(b for b, count in buckets if count >= q * total) * 1000

    return quantile(0.5), quantile(0.99)


def _percentiles(values: list[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    p50, p99 = np.percentile(np.asarray(values), [50, 99])
    return round(float(p50), 2), round(float(p99), 2)


def _prepare_database(kind: str, workdir: Path, robots: int) -> tuple[str, callable]:
    if kind == "sqlite":
        url = f"sqlite:///{workdir / f'bench-{time.time_ns()}.db'}"

        def drop() -> None:
            pass
    else:
        name = f"vigil_bench_{os.getpid()}_{int(time.time())}"
        admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}"'))
        url = PG_ADMIN_URL.rsplit("/", 1)[0] + f"/{name}"

        def drop() -> None:
            # FORCE ends the other sessions but gives up if they take more than 5 s to go (a
            # busy machine, a backend still shutting down): try again before leaving it behind.
            for attempt in range(4):
                try:
                    with admin.connect() as connection:
                        connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
                    break
                except DBAPIError:  # ObjectInUse
                    if attempt == 3:
                        raise
                    time.sleep(3)
            admin.dispose()

    upgrade(url)
    engine = make_engine(url)
    with transaction(make_session_factory(engine)) as session:
        for i in range(robots):
            session.add(
                Robot(
                    id=f"bench-{i}",
                    name=f"generated {i}",
                    ward=WARD,
                    token_hash=hash_robot_token(f"token-{i}"),
                )
            )
        session.add(
            User(
                username="nurse",
                password_hash=hash_password("bench-password"),
                role=Role.NURSE,
                ward=WARD,
            )
        )
        session.flush()
        session.add(
            User(
                username="engineer",
                password_hash=hash_password("bench-password"),
                role=Role.ENGINEER,
            )
        )
    engine.dispose()
    return url, drop


def _stored(url: str, seq_ranges: dict[str, tuple[int, int]]) -> tuple[int, int]:
    """Rows and distinct (robot, seq) in the database within each robot's sequence range of
    this run (first, last sent): an earlier run's frames on the same database are not counted."""
    engine = make_engine(url)
    rows = distinct = 0
    query = text(
        "SELECT count(*), count(DISTINCT seq) FROM frames "
        "WHERE robot_id = :robot AND seq BETWEEN :first AND :last"
    )
    with engine.connect() as connection:
        for robot_id, (first, last) in seq_ranges.items():
            params = {"robot": robot_id, "first": first, "last": last}
            n, d = connection.execute(query, params).one()
            rows += n
            distinct += d
    engine.dispose()
    return rows, distinct


async def _drive(server: BackendProcess, config: RunConfig, nurse_token: str) -> dict:
    alarms: dict[str, list[tuple[float, int]]] = {}
    ready = asyncio.Event()
    nurse = asyncio.create_task(nurse_client(server.ws, nurse_token, alarms, ready))
    await asyncio.wait_for(ready.wait(), 10)
    stop = asyncio.Event()
    stats = [RobotStats(f"bench-{i}") for i in range(config.robots)]
    clients = [
        asyncio.create_task(robot_client(server.ws, s.robot_id, f"token-{i}", config, stop, s))
        for i, s in enumerate(stats)
    ]
    # Warm-up: every robot connected, its transport and first alarm created, and the backlog
    # of that start drained (at most 15 s), so the window measures the steady state.
    await asyncio.sleep(2.0)
    deadline = time.perf_counter() + 13
    while time.perf_counter() < deadline:
        started = all(s.highest_ack >= 0 for s in stats)
        backlog = sum(len(s.unacked) for s in stats)
        if started and backlog <= config.robots * max(config.batch, 2) * (1 if config.hz else 4):
            break
        await asyncio.sleep(0.2)
    pids = server.pids()
    cpu0 = sum(_cpu_seconds(pid) for pid in pids)
    client_cpu0 = time.process_time()
    t0 = time.perf_counter()
    await asyncio.sleep(config.seconds)
    t1 = time.perf_counter()
    cpu1 = sum(_cpu_seconds(pid) for pid in pids)
    client_cpu1 = time.process_time()
    load = os.getloadavg()[0]
    stop.set()
    await asyncio.gather(*clients)
    # The window's last folds reach the board with the writer's trailing push (a robot that
    # stopped sending: UPDATE_PUSH_S and the grace after the alarm's last push).
    await asyncio.sleep(UPDATE_PUSH_S + TRAILING_PUSH_GRACE_S + 0.5)
    nurse.cancel()

    committed = sum(n for s in stats for t, n in s.ack_times if t0 <= t < t1)
    # Latencies of frames sent in the measurement window (not the warm-up, not the drain).
    ack = [ms for s in stats for sent, ms in s.ack_latency_ms if t0 <= sent < t1]
    alarm_latency = []
    for s in stats:
        pushes = sorted(alarms.get(s.robot_id, []))
        for seq, sent in s.emergency_at.items():
            if not t0 <= sent < t1:
                continue
            arrival = next((t for t, last in pushes if last >= seq and t >= sent), None)
            if arrival is not None:
                alarm_latency.append((arrival - sent) * 1000)
    emergencies = sum(1 for s in stats for sent in s.emergency_at.values() if t0 <= sent < t1)
    sent = sum(len(s.sent_at) for s in stats)
    ack50, ack99 = _percentiles(ack)
    al50, al99 = _percentiles(alarm_latency)
    flush = _histogram(server, "vigil_ingest_flush_seconds")
    return {
        "server_cpu_percent": round(100 * (cpu1 - cpu0) / (t1 - t0), 1),
        "server_cpu_us_per_frame": round(1e6 * (cpu1 - cpu0) / max(committed, 1), 1),
        "client_cpu_percent": round(100 * (client_cpu1 - client_cpu0) / (t1 - t0), 1),
        "flush_ms_p50_bucket": flush and flush[0],
        "flush_ms_p99_bucket": flush and flush[1],
        "load_average": round(load, 2),
        "sent": sent,
        "committed_in_window": committed,
        "frames_per_s": round(committed / (t1 - t0), 1),
        "ack_p50_ms": ack50,
        "ack_p99_ms": ack99,
        "alarm_p50_ms": al50,
        "alarm_p99_ms": al99,
        "emergencies_sent": emergencies,
        "emergencies_pushed": len(alarm_latency),
        "unacked_after_drain": sum(len(s.unacked) for s in stats),
        # Per robot, the first and last sequence number this run sent (for _stored).
        "seq_ranges": {s.robot_id: (s.first_seq, max(s.sent_at)) for s in stats if s.sent_at},
    }


def run(config: RunConfig, workdir: Path) -> dict:
    url, drop = _prepare_database(config.database, workdir, config.robots)
    env = {
        "VIGIL_DATABASE_URL": url,
        "VIGIL_SECRET_KEY": SECRET,
        "VIGIL_FRONTEND_DIR": str(workdir / "no-frontend"),
        "VIGIL_STREAM_STALL_SECONDS": "60",
        "VIGIL_ROBOT_OFFLINE_SECONDS": "60",
    }
    if config.workers > 1:
        env["VIGIL_REDIS_URL"] = REDIS_URL
        env["VIGIL_REDIS_CHANNEL"] = f"vigil-bench-{os.getpid()}-{time.time_ns()}"
    log = workdir / f"backend-{config.database}-{config.robots}.log"
    try:
        with BackendProcess(env, log_path=log, workers=config.workers) as server:
            nurse_token = create_access_token(SECRET, 1, 60)
            measured = asyncio.run(_drive(server, config, nurse_token))
        rows, distinct = _stored(url, measured["seq_ranges"])
    finally:
        drop()
    result = {
        "database": config.database,
        "robots": config.robots,
        "hz": config.hz or "max",
        "seconds": config.seconds,
        "frames_per_s": measured["frames_per_s"],
        "ack_p50_ms": measured["ack_p50_ms"],
        "ack_p99_ms": measured["ack_p99_ms"],
        "alarm_p50_ms": measured["alarm_p50_ms"],
        "alarm_p99_ms": measured["alarm_p99_ms"],
        "frames_lost": measured["sent"] - distinct,
        "duplicates": rows - distinct,
        "kind": "saturation" if not config.hz else "fleet",
        "frames_per_message": config.batch,
        "backend_workers": config.workers,
        "frames_sent": measured["sent"],
        "emergencies_sent": measured["emergencies_sent"],
        "emergencies_pushed": measured["emergencies_pushed"],
        "server_cpu_percent": measured["server_cpu_percent"],
        "server_cpu_us_per_frame": measured["server_cpu_us_per_frame"],
        "bench_client_cpu_percent": measured["client_cpu_percent"],
        "flush_ms_p50_bucket": measured["flush_ms_p50_bucket"],
        "flush_ms_p99_bucket": measured["flush_ms_p99_bucket"],
        "load_average_1min": measured["load_average"],
    }
    print(json.dumps(result), flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.ingest")
    parser.add_argument("--databases", default="sqlite,postgresql")
    parser.add_argument("--seconds", type=float, default=12)
    parser.add_argument("--saturation-robots", type=int, default=20)
    parser.add_argument("--only", choices=("saturation", "fleet"), default=None)
    parser.add_argument(
        "--workers",
        default="1,2",
        help="backend worker processes per run, comma-separated (2: alarms fan out via Redis)",
    )
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    runs = []
    with tempfile.TemporaryDirectory(prefix="vigil-bench-") as tmp:
        for workers in (int(w) for w in args.workers.split(",")):
            for database in args.databases.split(","):
                if args.only in (None, "saturation"):
                    config = RunConfig(
                        database, args.saturation_robots, 0, 50, args.seconds, 400, 997, workers
                    )
                    runs.append(run(config, Path(tmp)))
                if args.only in (None, "fleet"):
                    config = RunConfig(database, 100, 10, 1, args.seconds, 50, 20, workers)
                    runs.append(run(config, Path(tmp)))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(
        json.dumps(
            {
                "runs": runs,
                "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
                "note": (
                    "GENERATED frames (fixed skeleton), loopback websockets, backend defaults "
                    "(ingest_flush_ms 20). Latencies cover frames sent in the measurement window "
                    "after a warm-up; frames_lost/duplicates are checked in the database after "
                    "the run (each robot also replays its first batch). The machine is shared "
                    "with other jobs: see load_average_1min and server_cpu_percent; "
                    "server_cpu_us_per_frame is the backend's CPU cost per committed frame. "
                    "backend_workers 2: two uvicorn worker processes, alarms fanned out by Redis."
                ),
            },
            indent=2,
        )
        + "\n"
    )
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
