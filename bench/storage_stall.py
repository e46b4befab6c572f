"""Storage stall: the database write lock is held while a robot streams and decides an
Emergency. Measures how long the Emergency takes to reach the nurse board (browser websocket),
whether it came marked not yet stored, whether the storage-stalled technical alarm showed and
cleared, whether the stored alarm replaced the provisional one (same key, one alarm stored), and
how many frames were lost.

Real backend (uvicorn subprocess), real websockets. SQLite: a separate connection holds
BEGIN IMMEDIATE; PostgreSQL: LOCK TABLE frames IN EXCLUSIVE MODE in a separate connection.
The frames are GENERATED (tests.backend.test_first_alarm.frame); this measures the alarm path,
not detection.

    python -m bench.storage_stall [--lock-seconds 20] [--out bench/results/storage_stall.json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import sqlite3
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import httpx
from sqlalchemy import create_engine, func, select, text
from websockets.asyncio.client import connect

from backend.db import make_engine, make_session_factory
from backend.models import Alarm, AlarmEvent, Frame
from backend.models.alarms import AlarmKind
from backend.process import BackendProcess
from backend.settings import Settings
from vigil.protocol import Hello, TransportStart

GOAL_BOARD_MS = 1000
FPS = 30
BATCH = 3  # frames per message, as the robot agent batches them


@contextmanager
def write_lock(database_url: str):
    """Hold the database's write lock from a separate connection until the block ends."""
    if database_url.startswith("sqlite"):
        connection = sqlite3.connect(database_url.split("///", 1)[1], isolation_level=None)
        connection.execute("BEGIN IMMEDIATE")
        try:
            yield
        finally:
            connection.execute("ROLLBACK")
            connection.close()
        return
    engine = create_engine(database_url)
    connection = engine.connect()
    connection.execute(text("LOCK TABLE frames IN EXCLUSIVE MODE"))
    try:
        yield
    finally:
        connection.rollback()
        connection.close()
        engine.dispose()


def _frame(seq: int, decision: str, transport_id: str) -> dict:
    from tests.backend.test_first_alarm import frame

    return json.loads(frame(seq, decision, transport_id).model_dump_json())


async def stall_scenario(
    ws_base: str,
    database_url: str,
    nurse_token: str,
    robot_id: str,
    robot_token: str,
    lock_s: float,
    transport_id: str = "t-stall",
) -> dict:
    """Stream at 30 frames/s; hold the write lock `lock_s` seconds; send an Emergency 0.5 s
    into the lock. Returns what the nurse received (with times) and what was stored."""
    board: list[tuple[float, dict]] = []  # (perf_counter, alarm message) as the nurse got them
    acked = -1
    seq = 0
    sent: set[int] = set()
    emergency_seqs: list[int] = []
    t_emergency = t_lock = t_release = 0.0

    async with connect(f"{ws_base}/ws/browser") as nurse:
        await nurse.send(json.dumps({"type": "auth", "token": nurse_token}))
        snapshot = json.loads(await nurse.recv())
        assert snapshot["type"] == "snapshot", snapshot

        async def read_board() -> None:
            async for raw in nurse:
                message = json.loads(raw)
                if message.get("type") == "alarm":
                    board.append((time.perf_counter(), message["alarm"]))

        reader = asyncio.create_task(read_board())
        async with connect(f"{ws_base}/ws/robot") as robot:
            await robot.send(Hello(robot_id=robot_id, token=robot_token).model_dump_json())
            welcome = json.loads(await robot.recv())
            assert welcome["type"] == "welcome", welcome
            seq = (welcome["last_seq"] or -1) + 1
            first_seq = seq
            await robot.send(
                TransportStart(
                    transport_id=transport_id,
                    mode="wheelchair",
                    patient="P-7",
                    location="corridor B",
                    ts=time.time(),
                ).model_dump_json()
            )

            async def read_acks() -> None:
                nonlocal acked
                async for raw in robot:
                    message = json.loads(raw)
                    if message.get("type") == "ack":
                        acked = max(acked, message["seq"])

            acks = asyncio.create_task(read_acks())

            async def stream(seconds: float, decision: str = "normal") -> None:
                nonlocal seq
                end = time.perf_counter() + seconds
                while time.perf_counter() < end:
                    batch = [_frame(s, decision, transport_id) for s in range(seq, seq + BATCH)]
                    await robot.send(json.dumps({"type": "frames", "frames": batch}))
                    sent.update(range(seq, seq + BATCH))
                    if decision == "emergency":
                        emergency_seqs.extend(range(seq, seq + BATCH))
                    seq += BATCH
                    await asyncio.sleep(BATCH / FPS)

            await stream(1.0)
            with write_lock(database_url):
                t_lock = time.perf_counter()
                await stream(0.5)
                t_emergency = time.perf_counter()
                await stream(0.3, "emergency")
                await stream(max(0.0, lock_s - (time.perf_counter() - t_lock)))
                t_release = time.perf_counter()
            await stream(1.0)
            last = seq - 1
            deadline = time.monotonic() + 60
            while acked < last and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
            t_all_acked = time.perf_counter()
            acks.cancel()
        await asyncio.sleep(0.5)  # the last pushes
        reader.cancel()

    engine = make_engine(database_url)
    with make_session_factory(engine)() as session:
        counts = dict(
            session.execute(
                select(Frame.seq, func.count())
                .where(Frame.robot_id == robot_id, Frame.seq >= first_seq)
                .group_by(Frame.seq)
            ).all()
        )
        stored_emergencies = session.scalars(
            select(Alarm).where(
                Alarm.robot_id == robot_id,
                Alarm.transport_key == transport_id,
                Alarm.kind == AlarmKind.EMERGENCY,
            )
        ).all()
        stored = [(a.id, a.first_seq, a.last_seq) for a in stored_emergencies]
        stalls = session.scalars(
            select(Alarm).where(Alarm.robot_id == robot_id, Alarm.kind == AlarmKind.STORAGE_STALLED)
        ).all()
        stalls_stored = [
            {
                "id": a.id,
                "state": a.state,
                "blocked_s": (a.details or {}).get("blocked_s"),
                "events": [
                    e.action
                    for e in session.scalars(
                        select(AlarmEvent)
                        .where(AlarmEvent.alarm_id == a.id)
                        .order_by(AlarmEvent.id)
                    )
                ],
            }
            for a in stalls
        ]
    engine.dispose()

    def ms(t: float, since: float) -> float:
        return round((t - since) * 1000, 1)

    emergencies = [(t, a) for t, a in board if a["kind"] == "emergency"]
    stalled = [(t, a) for t, a in board if a["kind"] == "storage_stalled"]
    first_emergency = emergencies[0] if emergencies else None
    first_stored = next(((t, a) for t, a in emergencies if a.get("stored", True)), None)
    stalled_raised = next(((t, a) for t, a in stalled if a["state"] == "open"), None)
    stalled_cleared = next(((t, a) for t, a in stalled if a["state"] == "resolved"), None)
    return {
        "lock_seconds": round(t_release - t_lock, 2),
        "emergency_to_board_ms": ms(first_emergency[0], t_emergency) if first_emergency else None,
        "first_emergency_stored": first_emergency[1].get("stored", True)
        if first_emergency
        else None,
        "first_emergency": first_emergency[1] if first_emergency else None,
        "stored_emergency_after_release_ms": ms(first_stored[0], t_release)
        if first_stored
        else None,
        "stored_emergency": first_stored[1] if first_stored else None,
        "storage_stalled_after_lock_ms": ms(stalled_raised[0], t_lock) if stalled_raised else None,
        "storage_stalled_cleared_after_release_ms": ms(stalled_cleared[0], t_release)
        if stalled_cleared
        else None,
        "storage_stalled": stalled_raised[1] if stalled_raised else None,
        "storage_stalled_cleared": stalled_cleared[1] if stalled_cleared else None,
        "emergency_messages": [
            {
                "at_ms": ms(t, t_emergency),
                "id": a["id"],
                "key": a.get("key"),
                "stored": a.get("stored", True),
            }
            for t, a in emergencies
        ],
        "emergency_seqs": [min(emergency_seqs), max(emergency_seqs)],
        "alarms_stored": stored,
        "storage_stalled_stored": stalls_stored,
        "kinds_on_board": sorted({a["kind"] for _, a in board}),
        "frames_sent": len(sent),
        "frames_stored": len(counts),
        "frames_lost": len(sent - counts.keys()),
        "frames_duplicated": sum(1 for c in counts.values() if c > 1),
        "all_acked_after_release_ms": ms(t_all_acked, t_release),
    }


def run(lock_s: float) -> dict:
    from tests.support.live_backend import PASSWORD, ROBOT_ID, ROBOT_TOKEN, prepare_database

    with tempfile.TemporaryDirectory() as workdir:
        database_url = f"sqlite:///{Path(workdir) / 'vigil.db'}"
        prepare_database(database_url)  # nurse nina (ward-a), robot-a (ward-a)
        env = {
            "VIGIL_DATABASE_URL": database_url,
            "VIGIL_SECRET_KEY": "bench-storage-stall",
            "VIGIL_FRONTEND_DIR": str(Path(workdir) / "no-frontend"),
            # Default robot-offline (10 s) / stream-stalled (5 s) times, shorter than the lock:
            # `kinds_on_board` shows whether the monitor blamed the robot for storage's stall.
        }
        with BackendProcess(env, log_path=Path(workdir) / "backend.log") as backend:
            login = httpx.post(
                f"{backend.http}/api/auth/login", json={"username": "nina", "password": PASSWORD}
            )
            login.raise_for_status()
            token = login.json()["access_token"]
            result = asyncio.run(
                stall_scenario(backend.ws, database_url, token, ROBOT_ID, ROBOT_TOKEN, lock_s)
            )
    for heavy in (
        "first_emergency",
        "stored_emergency",
        "storage_stalled",
        "storage_stalled_cleared",
    ):
        result.pop(heavy)
    return {
        "what": "database write lock held while a robot streams at 30 frames/s and decides an "
        "Emergency 0.5 s into the lock: Emergency -> nurse board (browser websocket) latency, "
        "storage-stalled alarm, reconciliation, frames lost",
        "goal": {"emergency_to_board_ms": GOAL_BOARD_MS, "frames_lost": 0},
        "met": result["emergency_to_board_ms"] is not None
        and result["emergency_to_board_ms"] <= GOAL_BOARD_MS
        and result["frames_lost"] == 0,
        **result,
        "settings": {
            name: Settings.model_fields[name].default
            for name in ("storage_stall_seconds", "unstored_alarm_ms")
        },
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "database": "sqlite",
        },
        "measured_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lock-seconds", type=float, default=20.0)
    parser.add_argument("--out", type=Path, default=Path("bench/results/storage_stall.json"))
    args = parser.parse_args()
    result = run(args.lock_seconds)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
