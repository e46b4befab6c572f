"""`make bench-hospital-group`: a hospital group on one server (issue 36). Backend replicas
(uvicorn processes; two unless `--replicas`) over one PostgreSQL and Redis, robots streaming at
10 Hz over real websockets from several client processes, nurse boards spread over the
replicas, open alarms on the boards, the alarm distribution to an Alert Manager (the simulator,
real MLLP) and one retention run during the window; in the middle of it the replica that runs
the duties (alarm monitor, alarm distribution) is killed with -9.

Each robot is given every replica (each preferring one in turn) and, like the agent
(robot_agent/client.py), goes to the next at once when its connection drops, resending what
was not acknowledged after the welcome's last_seq. Measured:
- ack latency (frame sent -> ack covering it) and alarm latency (Emergency frame sent -> a
  board receives the alarm covering it), p50/p99, over the whole window including the kill;
  the ack goal is judged outside the failover (frames sent from 1 s before the kill to 5 s
  after it wait for their robot's reconnect, which the streaming-again goal judges);
- per robot of the killed replica: kill -> first ack from another replica;
- frames lost (acknowledged but not stored) and duplicated rows, checked in the database;
- Emergency alarms per transport (each transport decides Emergency once: exactly one alarm);
- technical alarms the monitor raised for the benchmark's robots (robot offline, stream stalled,
  patient not seen), by kind;
- which replica held the duties before and after the kill (/api/health; exactly one after it),
  the surviving replicas' CPU and RSS (summed).

Frames are GENERATED (fixed skeleton): this measures the system, not detection. Results go
into bench/results/ingest.json under "hospital_group" by robot count, and replica count where
it is not two (the other runs there are kept); `make bench-hospital-group` runs 100, 300 and
1,000 robots on two replicas. On a server with more cores (the robots' client processes best on
another machine), e.g. `--robots 1000 --replicas 8`.

    python -m bench.hospital_group [--robots 1000] [--processes 4] [--replicas 2] [--seconds 40]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import os
import platform
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
from sqlalchemy import text
from websockets.asyncio.client import connect

from backend.alarms.state import ALARM
from backend.db import make_engine, make_session_factory, transaction
from backend.models import Alarm, AlarmKind, Robot, Transport
from backend.models.alarms import AlarmPriority
from backend.process import BackendProcess, free_port
from backend.security import create_access_token, hash_robot_token
from bench.alarm_distribution import ThreadedAlertManager
from bench.ingest import _FRAME, REDIS_URL, _cpu_seconds, _prepare_database
from bench.ingest import _percentiles as ingest_percentiles

RESULTS = Path(__file__).resolve().parent / "results" / "ingest.json"
SECRET = "bench-secret"
WARD = "ward-bench"
GOALS = {"ack_p99_ms": 100, "alarm_p99_ms": 250, "streaming_again_s": 5}


# -- robots (in client processes) -----------------------------------------------------------
async def _robot(index: int, urls: list[str], hz: float, stop_at: float, emergency_at: float):
    """One robot: 10 Hz single-frame messages; decides Emergency from `emergency_at` on (its
    transport's one Emergency); fails over between `urls` like the agent."""
    robot_id, token = f"bench-{index}", f"token-{index}"
    transport = f"{robot_id}-t1"
    sent: dict[int, float] = {}  # seq -> wall time sent (not acknowledged yet)
    acks: list[tuple[float, float]] = []  # (sent, latency ms)
    emergencies: dict[int, float] = {}
    connections: list[tuple[float, str, float | None]] = []  # (connected at, url, first ack)
    # Like the agent's outbox: the start is resent on every connection until an ack on a
    # connection that carried it confirms it (a replica killed before committing it loses it).
    seq, url_index, start_confirmed = 0, index % len(urls), False
    while time.time() < stop_at:
        url = urls[url_index]
        try:
            async with connect(url + "/ws/robot", max_size=None, compression=None) as ws:
                await ws.send(json.dumps({"type": "hello", "robot_id": robot_id, "token": token}))
                welcome = json.loads(await ws.recv())
                last = welcome.get("last_seq")
                for s in [s for s in sent if last is not None and s <= last]:
                    acks.append((sent[s], (time.time() - sent.pop(s)) * 1000))
                connection = [time.time(), url, None]
                connections.append(connection)
                if not start_confirmed:
                    await ws.send(
                        json.dumps(
                            {
                                "type": "transport_start",
                                "transport_id": transport,
                                "mode": "walking",
                                "ts": time.time(),
                            }
                        )
                    )
                # resend what the backend does not have, in order
                for s in sorted(sent):
                    decision = "emergency" if s in emergencies else "normal"
                    await ws.send(
                        '{"type":"frames","frames":[%s]}'
                        % (_FRAME % (s, sent[s], transport, decision))
                    )

                async def receive(connection=connection) -> None:
                    nonlocal start_confirmed
                    async for raw in ws:
                        message = json.loads(raw)
                        if message.get("type") != "ack":
                            continue
                        start_confirmed = True  # handled in order: the start came first
                        now = time.time()
                        if connection[2] is None:
                            connection[2] = now
                        for s in [s for s in sent if s <= message["seq"]]:
                            acks.append((sent[s], (now - sent.pop(s)) * 1000))

                receiver = asyncio.create_task(receive())
                next_at = time.time()
                try:
                    while time.time() < stop_at and not receiver.done():
                        now = time.time()
                        decision = "emergency" if now >= emergency_at else "normal"
                        if decision == "emergency" and not emergencies:
                            emergencies[seq] = now
                        sent[seq] = now
                        await ws.send(
                            '{"type":"frames","frames":[%s]}'
                            % (_FRAME % (seq, now, transport, decision))
                        )
                        seq += 1
                        next_at += 1 / hz
                        await asyncio.sleep(max(0.0, next_at - time.time()))
                    # drain
                    deadline = time.time() + 10
                    while sent and time.time() < deadline and not receiver.done():
                        await asyncio.sleep(0.05)
                finally:
                    receiver.cancel()
                if time.time() >= stop_at:
                    break
        except Exception:  # noqa: BLE001 - the replica went away: try the other
            pass
        url_index = (url_index + 1) % len(urls)  # the other replica, at once
    return {
        "robot_id": robot_id,
        "acks": acks,
        "emergencies": emergencies,
        "connections": connections,
        "sent": seq,
        "unacked": len(sent),
        "unacked_seqs": sorted(sent),
    }


def _client_process(indices, urls, hz, stop_at, emergency_at, out) -> None:
    async def fleet():
        return await asyncio.gather(
            *(_robot(i, urls, hz, stop_at, emergency_at + (i % 50) * 0.1) for i in indices)
        )

    results = asyncio.run(fleet())
    Path(out).write_text(json.dumps(results))


# -- boards -----------------------------------------------------------------------------------
async def _board(url: str, token: str, arrivals: list, stop_at: float, ready: asyncio.Event):
    while time.time() < stop_at:
        try:
            async with connect(
                f"{url}/ws/browser",
                max_size=None,
                additional_headers={"Authorization": f"Bearer {token}"},
            ) as ws:
                json.loads(await ws.recv())  # snapshot
                ready.set()
                while time.time() < stop_at:
                    try:
                        raw = await asyncio.wait_for(ws.recv(), 1)
                    except TimeoutError:
                        continue
                    message = json.loads(raw)
                    if message.get("type") == "alarm" and message["alarm"]["kind"] == "emergency":
                        alarm = message["alarm"]
                        arrivals.append((time.time(), alarm["robot_id"], alarm["last_seq"]))
        except Exception:  # noqa: BLE001 - its replica died: the board reconnects
            await asyncio.sleep(0.5)


async def _boards(urls, token, stop_at) -> list:
    arrivals: list = []
    readies = [asyncio.Event() for _ in range(5)]
    tasks = [
        asyncio.create_task(_board(urls[i % len(urls)], token, arrivals, stop_at, readies[i]))
        for i in range(5)
    ]
    await asyncio.gather(*tasks)
    return arrivals


# -- the run -----------------------------------------------------------------------------------
def _seed(url: str, open_alarms: int) -> None:
    engine = make_engine(url)
    factory = make_session_factory(engine)
    with transaction(factory) as session:
        session.add(
            Robot(
                id="seeded",
                name="GENERATED seeded alarms",
                ward=WARD,
                token_hash=hash_robot_token("seeded"),
            )
        )
        session.flush()
        for i in range(open_alarms):
            session.add(Transport(id=f"seeded-t{i}", robot_id="seeded", mode="walking"))
        session.flush()
        for i in range(open_alarms):  # GENERATED open alarms the boards carry
            alarm = Alarm(
                robot_id="seeded",
                ward=WARD,
                transport_id=f"seeded-t{i}",
                transport_key=f"seeded-t{i}",
                kind=AlarmKind.EMERGENCY,
                priority=AlarmPriority.HIGH,
                first_seq=i,
                last_seq=i,
            )
            ALARM.start(alarm)
            session.add(alarm)
    engine.dispose()


def _rss_bytes(pid: int) -> int:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[21]) * os.sysconf("SC_PAGE_SIZE")


def _duties(server: BackendProcess) -> dict | None:
    import httpx

    try:
        return httpx.get(f"{server.http}/api/health", timeout=5).json().get("duties")
    except Exception:  # noqa: BLE001
        return None


def _percentiles(values) -> dict:
    p50, p99 = ingest_percentiles(values)
    return {"p50": p50, "p99": p99}


def replica_names(count: int) -> list[str]:
    """a, b, c, ... (the names README's runs were made with), then r27, r28, ..."""
    return [chr(ord("a") + i) if i < 26 else f"r{i + 1}" for i in range(count)]


def run_key(robots: int, replicas: int) -> str:
    """Where a run goes in ingest.json's hospital_group: two replicas are the runs of record."""
    return f"{robots}_robots" if replicas == 2 else f"{robots}_robots_{replicas}_replicas"


def run(args) -> dict:
    servers: dict[str, BackendProcess] = {}
    url, drop = _prepare_database("postgresql", Path("/tmp"), args.robots)
    manager = ThreadedAlertManager(free_port())
    manager.start()
    try:
        _seed(url, args.open_alarms)
        env = {
            "VIGIL_DATABASE_URL": url,
            "VIGIL_SECRET_KEY": SECRET,
            "VIGIL_FRONTEND_DIR": "/nonexistent",
            "VIGIL_REDIS_URL": REDIS_URL,
            "VIGIL_REDIS_CHANNEL": f"vigil-bench-group-{uuid.uuid4().hex}",
            "VIGIL_ALERT_MANAGER": f"127.0.0.1:{manager.simulator.port}",
            "VIGIL_STREAM_STALL_SECONDS": "60",
            "VIGIL_ROBOT_OFFLINE_SECONDS": "60",
        }
        logs = Path(args.log_dir)
        logs.mkdir(parents=True, exist_ok=True)
        for name in replica_names(args.replicas):
            servers[name] = BackendProcess(
                {**env, "VIGIL_REPLICA_NAME": name}, log_path=logs / f"{name}.log"
            ).start(60)
        duties_before = {name: _duties(server) for name, server in servers.items()}
        leader_name = next(
            (name for name, duties in duties_before.items() if (duties or {}).get("leading")),
            list(servers)[-1],
        )
        leader = servers[leader_name]
        survivors = {name: s for name, s in servers.items() if name != leader_name}
        start = time.time() + 5
        stop_at = start + args.warmup_s + args.seconds
        kill_at = start + args.warmup_s + args.seconds / 2
        emergency_at = start + args.warmup_s + args.seconds / 4
        urls = [server.ws for server in servers.values()]
        chunks = np.array_split(np.arange(args.robots), args.processes)
        outs = [logs / f"clients-{i}.json" for i in range(len(chunks))]
        clients = [
            multiprocessing.get_context("spawn").Process(
                target=_client_process,
                args=(list(map(int, chunk)), urls, args.hz, stop_at, emergency_at, str(out)),
            )
            for chunk, out in zip(chunks, outs, strict=True)
        ]
        for client in clients:
            client.start()
        nurse_token = create_access_token(SECRET, 1, 120)
        retention = None
        cpu0 = {name: _cpu_seconds(server.process.pid) for name, server in servers.items()}

        async def watch() -> tuple[list, float]:
            boards = asyncio.create_task(_boards(urls, nurse_token, stop_at))
            nonlocal retention
            await asyncio.sleep(max(0.0, start + args.warmup_s - time.time()))
            window_started = time.time()
            retention = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    (
                        "import sys; from backend.db import make_engine, make_session_factory; "
                        "from backend.settings import Settings; "
                        "from backend.storage.retention import run_retention; "
                        f"factory = make_session_factory(make_engine({url!r})); "
                        "print(run_retention(factory, Settings()))"
                    ),
                ],
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                env={**os.environ, "VIGIL_DATABASE_URL": url},
            )
            await asyncio.sleep(max(0.0, kill_at - time.time()))
            return await boards, window_started

        async def kill_later():
            await asyncio.sleep(max(0.0, kill_at - time.time()))
            leader.kill()

        async def both():
            return await asyncio.gather(watch(), kill_later())

        (arrivals, window_started), _ = asyncio.run(both())
        for client in clients:
            client.join(120)
        # summed over the surviving replicas (one, with the default two)
        survivor_rss = sum(_rss_bytes(s.process.pid) for s in survivors.values())
        cpu_seconds = sum(_cpu_seconds(s.process.pid) - cpu0[name] for name, s in survivors.items())
        duties_after_by_replica = {name: _duties(s) for name, s in survivors.items()}
        duties_after = next(
            (d for d in duties_after_by_replica.values() if (d or {}).get("leading")),
            next(iter(duties_after_by_replica.values())),
        )
        leaders_after = sum(1 for d in duties_after_by_replica.values() if (d or {}).get("leading"))
        retention_output = retention.communicate(timeout=120)[0][-500:] if retention else None
        robots = [r for out in outs for r in json.loads(out.read_text())]
        killed_url = leader.ws
        for server in survivors.values():
            server.stop()
        # -- the database's view
        engine = make_engine(url)
        with engine.connect() as connection:
            stored = dict(
                connection.execute(
                    text("SELECT robot_id, count(*) FROM frames GROUP BY robot_id")
                ).all()
            )
            distinct = dict(
                connection.execute(
                    text("SELECT robot_id, count(DISTINCT seq) FROM frames GROUP BY robot_id")
                ).all()
            )
            stored_seqs: dict[str, set[int]] = {}
            for robot_id, seq in connection.execute(text("SELECT robot_id, seq FROM frames")):
                stored_seqs.setdefault(robot_id, set()).add(seq)
            per_transport = connection.execute(
                text(
                    "SELECT robot_id, transport_key, count(*) FROM alarms "
                    "WHERE kind = 'emergency' AND robot_id LIKE 'bench-%' "
                    "GROUP BY robot_id, transport_key"
                )
            ).all()
            technical = dict(
                connection.execute(
                    text(
                        "SELECT kind, count(*) FROM alarms WHERE robot_id LIKE 'bench-%' "
                        "AND kind IN ('robot_offline', 'stream_stalled', 'patient_not_seen') "
                        "GROUP BY kind"
                    )
                ).all()
            )
            distributed = connection.scalar(
                text("SELECT count(*) FROM alarm_messages WHERE status = 'delivered'")
            )
        engine.dispose()
    finally:
        manager.stop()
        for server in servers.values():
            server.stop()
        drop()

    window = (window_started, stop_at)
    ack = [ms for r in robots for sent, ms in r["acks"] if window[0] <= sent < window[1]]
    # The failover has its own goal (streaming again within 5 s): frames sent from 1 s before
    # the kill to 5 s after it are judged by that one, not by the steady ack goal.
    failover = (kill_at - 1, kill_at + GOALS["streaming_again_s"])
    steady = [
        ms
        for r in robots
        for sent, ms in r["acks"]
        if window[0] <= sent < window[1] and not failover[0] <= sent < failover[1]
    ]
    alarm_ms = []
    for r in robots:
        for seq, sent in r["emergencies"].items():
            seq = int(seq)
            arrival = min(
                (
                    t
                    for t, robot, last in arrivals
                    if robot == r["robot_id"] and last is not None and last >= seq and t >= sent
                ),
                default=None,
            )
            if arrival is not None:
                alarm_ms.append((arrival - sent) * 1000)
    again = []
    for r in robots:
        after = [c for c in r["connections"] if c[0] >= kill_at - 0.5 and c[2] is not None]
        before = [c for c in r["connections"] if c[0] < kill_at]
        if before and before[-1][1] == killed_url and after:
            again.append(after[0][2] - kill_at)
    sent = sum(r["sent"] for r in robots)
    # acknowledged (sent and not left unacknowledged) but not in the database
    lost = 0
    for r in robots:
        acked = set(range(r["sent"])) - set(r["unacked_seqs"])
        lost += len(acked - stored_seqs.get(r["robot_id"], set()))
    duplicates = sum(stored.values()) - sum(distinct.values())
    alarms_per_transport = [n for _, _, n in per_transport]
    without_transport = sum(n for _, key, n in per_transport if key == "")
    measured = {
        "robots": args.robots,
        "hz": args.hz,
        "client_processes": args.processes,
        "window_s": args.seconds,
        "frames_sent": sent,
        "frames_per_s_offered": round(args.robots * args.hz, 1),
        "ack_ms": _percentiles(ack),
        "ack_ms_outside_failover": _percentiles(steady),
        "alarm_frame_to_board_ms": _percentiles(alarm_ms),
        "emergencies": sum(len(r["emergencies"]) for r in robots),
        "emergencies_on_a_board": len(alarm_ms),
        "kill_9": {
            "replica_killed": leader_name,
            "its_robots": len(
                [r for r in robots if r["connections"] and r["connections"][0][1] == killed_url]
            ),
            "streaming_again_s": {
                **_percentiles(again),
                "max": round(max(again), 2) if again else None,
            },
        },
        "frames_lost": lost,
        "unacknowledged_at_end": sum(r["unacked"] for r in robots),
        "duplicated_rows": duplicates,
        "emergency_alarms_per_transport": {
            "transports": len(alarms_per_transport),
            "more_than_one": sum(1 for n in alarms_per_transport if n > 1),
            # Emergency alarms of frames whose transport the backend never heard start
            "without_transport": without_transport,
        },
        # Raised by the monitor for the benchmark's robots, which stream their patient
        # throughout: each one is an outage the boards were shown (the kill's own included).
        "technical_alarms": {
            kind: technical.get(kind, 0)
            for kind in ("robot_offline", "stream_stalled", "patient_not_seen")
        },
        "alarm_messages_delivered": distributed,
        "open_alarms_seeded": args.open_alarms,
        "boards": 5,
        "retention": retention_output,
        "replicas": args.replicas,
        "duties": {
            "before": duties_before,
            "after_kill": duties_after,
            "replicas_leading_after_kill": leaders_after,
        },
        "surviving_backend": {
            "cpu_percent": round(100 * cpu_seconds / (time.time() - window[0]), 1),
            "rss_mb": round(survivor_rss / 2**20, 1),
        },
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    measured["goals"] = GOALS
    measured["met"] = bool(
        measured["ack_ms_outside_failover"]["p99"] is not None
        and measured["ack_ms_outside_failover"]["p99"] <= GOALS["ack_p99_ms"]
        and measured["alarm_frame_to_board_ms"]["p99"] is not None
        and measured["alarm_frame_to_board_ms"]["p99"] <= GOALS["alarm_p99_ms"]
        and again
        and max(again) <= GOALS["streaming_again_s"]
        and lost == 0
        and duplicates == 0
        and measured["emergency_alarms_per_transport"]["more_than_one"] == 0
        and measured["emergency_alarms_per_transport"]["without_transport"] == 0
        and duties_after
        and duties_after.get("leading")
        and leaders_after == 1
    )
    return measured


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.hospital_group")
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--hz", type=float, default=10)
    parser.add_argument("--processes", type=int, default=4, help="robot client processes")
    parser.add_argument(
        "--replicas",
        type=int,
        default=2,
        help="backend replicas (at least 2; the one running the duties is killed)",
    )
    parser.add_argument("--seconds", type=float, default=40, help="measured window")
    parser.add_argument("--warmup-s", type=float, default=10)
    parser.add_argument("--open-alarms", type=int, default=500)
    parser.add_argument("--log-dir", default="/tmp/vigil-bench-hospital-group")
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    if args.replicas < 2:
        parser.error("--replicas: at least 2 (one is killed, another takes over)")
    result = run(args)
    result["machine"] = {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "database": "postgresql",
    }
    result["measured_at"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    existing = json.loads(args.output.read_text()) if args.output.exists() else {}
    existing.setdefault("hospital_group", {})[run_key(args.robots, args.replicas)] = result
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(existing, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
