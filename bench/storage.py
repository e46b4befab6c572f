"""`make bench-storage`: frames at hospital scale (issue 20). Writes bench/results/storage.json.

Per database (PostgreSQL, SQLite), with GENERATED history (transports of generated robots
"hist-*": a random but fixed skeleton per robot, 10 Hz, spread over --days days ending now; every
50th transport has an alarm in its middle, every 100th a label), loaded with COPY on PostgreSQL
(`backend.ingest.bulk`, the ingest path's own bulk insert) and executemany on SQLite:
- sizes on disk after loading;
- ingest of --robots robots at 10 Hz (bench.ingest's fleet run: real backend, websockets): on
  an empty database and with the history loaded;
- alarm replay (GET /api/alarms/{id}/replay, 30 s each side) and labelling timeline
  (GET /api/videos/{id}/frames, 300 frames) latencies through the backend, history loaded;
- training export: the URFD training set (real data, all 70 recordings imported) read into the
  training code's FrameData (`worker.db_data.frame_data`), history loaded;
- a retention run (policy defaults: 30 days, alarm windows, labels) while the robots stream, in
  a process of its own (as the worker runs it; in the bench process it would starve the
  simulated robots): ack p99, frames lost, every frame the policy keeps checked by id
  afterwards, the retention process's CPU seconds. The robots of that run number their frames
  after the welcome's last_seq, as the robot agent does, so their batches skip the ingest's
  duplicate check (`backend.ingest.service._existing_seqs`: a frames query without a ts bound,
  which plans over every partition and so waits while retention holds a day partition's
  TRUNCATE lock; only a batch holding a seq at or below the stored last seq runs it);
- space: bytes after retention against before - dropped x bytes per frame (+ frames ingested).
Sizes are parameters (--pg-frames, --sqlite-frames); the JSON says what was run.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import os
import platform
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np
from sqlalchemy import text

from backend.db import make_engine, make_session_factory, transaction
from backend.ingest.bulk import insert_frame_rows
from backend.labelling.status import SEGMENT
from backend.metrics import summary_ms
from backend.models import Alarm, AlarmKind, AnnotationSegment, Robot, Video
from backend.models.alarms import PRIORITY_OF_KIND
from backend.process import BackendProcess
from backend.security import create_access_token
from backend.storage import partitions, queries
from backend.storage.policy import DAY_S, RetentionPolicy, day_of
from backend.storage.retention import run_retention
from backend.storage.settings import StorageSettings
from bench import ingest
from bench.timing_lock import timed_phase
from vigil.skeleton import encode_depth, encode_floor, encode_keypoints

RESULTS = Path(__file__).resolve().parent / "results" / "storage.json"
VIDEO_FRAMES = 3000  # a 5-minute transport at 10 Hz


def load_history(url: str, frames: int, robots: int, days: float, now: float) -> dict:
    """Generated transports spread evenly over `days` days before `now`."""
    engine = make_engine(url)
    factory = make_session_factory(engine)
    n_videos = max(1, frames // VIDEO_FRAMES)
    span = days * DAY_S / n_videos
    start0 = now - days * DAY_S
    rng = np.random.default_rng(20)
    blobs = [
        (
            encode_keypoints(rng.normal(300, 80, (25, 3)).astype(np.float32)),
            encode_depth(rng.uniform(1, 4, 25).astype(np.float32)),
            encode_floor(rng.normal(0.5, 0.3, 3).astype(np.float32)),
        )
        for _ in range(robots)
    ]
    started = time.perf_counter()
    with transaction(factory) as session:
        for r in range(robots):
            session.add(Robot(id=f"hist-{r}", name=f"generated history {r}", ward=ingest.WARD))
        if url.startswith("postgresql"):
            first, last = day_of(start0), day_of(now)
            partitions.ensure_partitions(session.connection(), range(first, last + 1))
    seqs = [0] * robots
    alarms = labelled = 0
    for k in range(n_videos):
        robot = k % robots
        t0 = start0 + k * span
        with transaction(factory) as session:
            video = Video(
                name=f"hist-transport-{k}",
                source="robot",
                generated=True,
                mode="walking",
                fps=10.0,
                robot_id=f"hist-{robot}",
                frame_count=VIDEO_FRAMES,
                first_frame_ts=t0,
                last_frame_ts=t0 + (VIDEO_FRAMES - 1) * 0.1,
            )
            session.add(video)
            session.flush()
            kp, depth, floor = blobs[robot]
            s0 = seqs[robot]
            rows = [
                (
                    video.id,
                    i,
                    t0 + i * 0.1,
                    f"hist-{robot}",
                    s0 + i,
                    kp,
                    depth,
                    floor,
                    "normal",
                    '{"normal": 0.93, "emergency": 0.07}',
                    "bench-1",
                    0.5,
                    300,
                    None,
                    None,
                    None,
                )
                for i in range(VIDEO_FRAMES)
            ]
            insert_frame_rows(session, rows)
            seqs[robot] += VIDEO_FRAMES
            if k % 50 == 0:
                mid = t0 + VIDEO_FRAMES * 0.05
                session.add(
                    Alarm(
                        kind=AlarmKind.EMERGENCY,
                        priority=PRIORITY_OF_KIND[AlarmKind.EMERGENCY],
                        robot_id=f"hist-{robot}",
                        ward=ingest.WARD,
                        state="resolved",
                        video_id=video.id,
                        first_frame_ts=mid,
                        last_frame_ts=mid + 5,
                        first_seq=s0 + 1500,
                        last_seq=s0 + 1550,
                    )
                )
                alarms += 1
            if k % 100 == 1:
                segment = AnnotationSegment(
                    video_id=video.id,
                    first_frame=100,
                    last_frame=400,
                    label_key="walking",
                    taxonomy_version=1,
                )
                SEGMENT.start(segment, "import")  # history as a dataset's accepted labels
                session.add(segment)
                labelled += 1
    seconds = time.perf_counter() - started
    with engine.connect() as connection:
        if url.startswith("postgresql"):
            connection.execution_options(isolation_level="AUTOCOMMIT").exec_driver_sql("ANALYZE")
        else:
            connection.exec_driver_sql("ANALYZE")
    engine.dispose()
    return {
        "frames": n_videos * VIDEO_FRAMES,
        "videos": n_videos,
        "alarms": alarms,
        "labelled_videos": labelled,
        "days": days,
        "robots": robots,
        "load_seconds": round(seconds, 1),
        "frames_per_s": round(n_videos * VIDEO_FRAMES / seconds),
    }


def disk(url: str) -> dict:
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        out = queries.database_bytes(session)
        out["frames"] = queries.total_frames(session)
    engine.dispose()
    if out["frames_bytes"] is None:  # SQLite: the file less its free pages
        out["frames_bytes"] = out["database_bytes"] - (out["free_bytes"] or 0)
    return out


def ingest_run(url: str, config: ingest.RunConfig, workdir: Path, during=None) -> dict:
    """bench.ingest's fleet run on an existing database; `during(server)` runs in a thread
    while the robots stream."""
    env = {
        "VIGIL_DATABASE_URL": url,
        "VIGIL_SECRET_KEY": ingest.SECRET,
        "VIGIL_FRONTEND_DIR": str(workdir / "no-frontend"),
        "VIGIL_STREAM_STALL_SECONDS": "60",
        "VIGIL_ROBOT_OFFLINE_SECONDS": "60",
    }
    log = workdir / f"backend-storage-{time.time_ns()}.log"
    extra: dict = {}
    with BackendProcess(env, log_path=log) as server:
        thread = None
        if during is not None:
            thread = threading.Thread(target=lambda: extra.update(during(server)))
            thread.start()
        token = create_access_token(ingest.SECRET, 1, 60)
        measured = asyncio.run(ingest._drive(server, config, token))
        if thread is not None:
            thread.join()
    rows, distinct = ingest._stored(url, measured["seq_ranges"])  # this run's frames only
    return {
        "ack_p50_ms": measured["ack_p50_ms"],
        "ack_p99_ms": measured["ack_p99_ms"],
        "alarm_p50_ms": measured["alarm_p50_ms"],
        "alarm_p99_ms": measured["alarm_p99_ms"],
        "frames_per_s": measured["frames_per_s"],
        "frames_sent": measured["sent"],
        "emergencies_sent": measured["emergencies_sent"],
        "emergencies_pushed": measured["emergencies_pushed"],
        "frames_lost": measured["sent"] - distinct,
        "duplicates": rows - distinct,
        "server_cpu_percent": measured["server_cpu_percent"],
        "load_average_1min": measured["load_average"],
        **extra,
    }


def reads(server: BackendProcess, url: str, samples: int) -> dict:
    """Alarm replay and labelling timeline loads through the backend (engineer token)."""
    engine = make_engine(url)
    with engine.connect() as connection:
        alarm_sql = "SELECT id FROM alarms WHERE robot_id LIKE 'hist-%' ORDER BY id"
        video_sql = "SELECT id FROM videos WHERE name LIKE 'hist-%' ORDER BY id"
        alarm_ids = connection.execute(text(alarm_sql)).scalars().all()
        video_ids = connection.execute(text(video_sql)).scalars().all()
    engine.dispose()
    token = create_access_token(ingest.SECRET, 2, 60)
    rng = np.random.default_rng(1)
    replay, timeline = [], []
    with httpx.Client(
        base_url=server.http, headers={"Authorization": f"Bearer {token}"}, timeout=30
    ) as client:
        for _ in range(samples):
            alarm = int(rng.choice(alarm_ids))
            t = time.perf_counter()
            response = client.get(
                f"/api/alarms/{alarm}/replay", params={"before_s": 30, "after_s": 30}
            )
            replay.append((time.perf_counter() - t) * 1000)
            assert response.status_code == 200 and response.json()["frames"], response.text[:200]
            video = int(rng.choice(video_ids))
            start = int(rng.integers(0, VIDEO_FRAMES - 300))
            t = time.perf_counter()
            response = client.get(
                f"/api/videos/{video}/frames", params={"start": start, "end": start + 299}
            )
            timeline.append((time.perf_counter() - t) * 1000)
            assert response.status_code == 200 and len(response.json()) == 300
    return {"alarm_replay": summary_ms(replay), "labelling_timeline": summary_ms(timeline)}


def training_export(url: str) -> dict:
    from backend.labelling.importers.urfd import import_urfd
    from backend.models.videos import Split
    from vigil.classes import TransportMode
    from worker.db_data import frame_data, labelled_videos

    engine = make_engine(url)
    factory = make_session_factory(engine)
    with transaction(factory) as session:
        names = {video.name for video in import_urfd(session, split=Split.TRAIN).videos}
    with transaction(factory) as session:
        started = time.perf_counter()
        videos = [
            v
            for v in labelled_videos(session, TransportMode.WALKING, Split.TRAIN)
            if v.name in names
        ]
        data = frame_data(session, videos, TransportMode.WALKING)
        seconds = time.perf_counter() - started
    engine.dispose()
    return {
        "recordings": len(data.names),
        "frames": int(len(data.target)),
        "seconds": round(seconds, 2),
        "data": "URFD (real), 70 recordings",
    }


def old_frames(url: str, cutoff: float) -> dict[int, tuple]:
    """Robot history frames older than the cutoff: id -> (video_id, robot_id, ts, index)."""
    engine = make_engine(url)
    with engine.connect() as connection:
        result = connection.execute(
            text(
                'SELECT id, video_id, robot_id, ts, "index" FROM frames '
                "WHERE robot_id IS NOT NULL AND ts < :c"
            ).execution_options(stream_results=True, yield_per=50000),
            {"c": cutoff},
        )
        out = {row[0]: row[1:] for row in result}
    engine.dispose()
    return out


def _retention_process(url: str, now: float, out) -> None:
    """The body of the retention's own process: one run, its summary and the CPU it spent."""
    engine = make_engine(url)
    try:
        result = run_retention(make_session_factory(engine), StorageSettings(), now=now)
        out.put({"result": result, "cpu_seconds": round(time.process_time(), 2)})
    except BaseException as error:
        out.put({"error": f"{type(error).__name__}: {error}"[:2000]})
        raise
    finally:
        engine.dispose()


def retention_in_own_process(url: str, now: float) -> tuple[dict, float]:
    """run_retention in a process of its own (as the worker runs it), not in the bench process
    whose asyncio loop drives the simulated robots: its Python would starve them and the acks
    measured would be the bench's delay, not the backend's. Returns (summary, CPU seconds)."""
    context = multiprocessing.get_context("spawn")  # the bench process has threads running
    out = context.Queue()
    process = context.Process(target=_retention_process, args=(url, now, out), daemon=True)
    process.start()
    try:
        answer = out.get()  # before join: a large result must be read for the child to end
    finally:
        process.join()
    if "error" in answer:
        raise RuntimeError(f"retention process failed: {answer['error']}")
    return answer["result"], answer["cpu_seconds"]


def retention_under_load(url: str, config: ingest.RunConfig, workdir: Path, now: float) -> dict:
    settings = StorageSettings()
    engine = make_engine(url)
    factory = make_session_factory(engine)
    with factory() as session:
        facts = queries.policy_facts(session, RetentionPolicy.from_settings(settings), now)
    before_old = old_frames(url, facts.cutoff)
    kept_expected = {i for i, (v, r, ts, idx) in before_old.items() if facts.reason(v, r, ts, idx)}
    space_before = disk(url)
    timing: dict = {}

    def retention(_server) -> dict:
        time.sleep(config.seconds * 0.1 + 8)  # into the measurement window (after warm-up)
        started = time.perf_counter()
        try:
            timing["result"], timing["cpu_seconds"] = retention_in_own_process(url, now)
        except Exception as error:
            timing["error"] = f"{type(error).__name__}: {error}"[:500]
            raise
        timing["seconds"] = round(time.perf_counter() - started, 1)
        return {}

    streaming = ingest_run(url, config, workdir, during=retention)
    after_old = set(old_frames(url, facts.cutoff))
    space_after = disk(url)
    engine.dispose()
    result = timing["result"]
    dropped = result["dropped_frames"]
    per_frame = space_before["frames_bytes"] / max(1, space_before["frames"])
    added = space_after["frames"] - (space_before["frames"] - dropped)
    predicted = space_before["frames_bytes"] - dropped * per_frame + added * per_frame
    return {
        "dropped_frames": dropped,
        "dropped_payload_bytes": result["dropped_bytes"],
        "kept_old_frames_by_reason": result["kept"],
        "partitions_replaced": len(result["partitions_dropped"]),
        "retention_seconds": timing["seconds"],
        "retention_process_cpu_seconds": timing["cpu_seconds"],
        "sqlite_chunk_write_hold_ms": result.get("chunk_hold_ms"),
        "measurement_window_s": config.seconds,
        "retention_finished_inside_window": timing["seconds"] + config.seconds * 0.1 + 8
        < config.seconds + 2,
        "ingest_during": streaming,
        "kept_frames_checked": len(kept_expected),
        "kept_frames_all_present": kept_expected <= after_old,
        "old_frames_left_exactly_the_kept": after_old == kept_expected,
        "space": {
            "before": space_before,
            "after": space_after,
            "bytes_per_frame_before": round(per_frame, 1),
            "frames_added_by_ingest": added,
            "predicted_frames_bytes": round(predicted),
            "actual_frames_bytes": space_after["frames_bytes"],
            "actual_over_predicted": round(space_after["frames_bytes"] / predicted, 3),
        },
    }


def bench_database(kind: str, frames: int, args, workdir: Path) -> dict:
    now = time.time()
    fleet = ingest.RunConfig(kind, args.robots, 10, 1, args.seconds, 50, 20)
    url, drop = ingest._prepare_database(kind, workdir, args.robots)
    try:
        history = load_history(url, frames, args.history_robots, args.days, now)
        loaded = disk(url)
        print(json.dumps({"history": history, "disk": loaded}), flush=True)
        with timed_phase(f"{kind}: ingest (empty and with the history), reads, export, retention"):
            empty = ingest.run(fleet, workdir)
            with_history = ingest_run(url, fleet, workdir)
            env = {
                "VIGIL_DATABASE_URL": url,
                "VIGIL_SECRET_KEY": ingest.SECRET,
                "VIGIL_FRONTEND_DIR": str(workdir / "no-frontend"),
            }
            with BackendProcess(env, log_path=workdir / f"reads-{kind}.log") as server:
                read = reads(server, url, args.read_samples)
            export = training_export(url)
            print(json.dumps({"reads": read, "training_export": export}), flush=True)
            retention_config = ingest.RunConfig(
                kind, args.robots, 10, 1, args.retention_window, 50, 20
            )
            retention = retention_under_load(url, retention_config, workdir, now)
    finally:
        try:
            drop()
        except Exception as error:  # a session still open must not hide the real error
            print(f"could not drop the bench database: {error}", flush=True)
    ratio = (with_history["ack_p99_ms"] or 0) / max(1e-9, empty["ack_p99_ms"] or 1e-9)
    return {
        "database": kind,
        "history": history,
        "disk_after_loading": loaded,
        "ingest_empty": {
            k: empty[k]
            for k in (
                "ack_p50_ms",
                "ack_p99_ms",
                "alarm_p50_ms",
                "alarm_p99_ms",
                "frames_per_s",
                "frames_lost",
                "load_average_1min",
            )
        },
        "ingest_with_history": with_history,
        "ack_p99_with_history_over_empty": round(ratio, 3),
        "reads_with_history": read,
        "training_export": export,
        "retention": retention,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.storage")
    parser.add_argument("--databases", default="postgresql,sqlite")
    parser.add_argument("--pg-frames", type=int, default=20_100_000)
    parser.add_argument("--sqlite-frames", type=int, default=5_100_000)
    parser.add_argument("--days", type=float, default=40, help="history spread over this many days")
    parser.add_argument("--history-robots", type=int, default=100)
    parser.add_argument("--robots", type=int, default=100, help="robots streaming at 10 Hz")
    parser.add_argument("--seconds", type=float, default=12)
    parser.add_argument("--retention-window", type=float, default=60)
    parser.add_argument("--read-samples", type=int, default=300)
    parser.add_argument("--output", type=Path, default=RESULTS)
    parser.add_argument(
        "--append", action="store_true", help="keep the output file's runs of the other databases"
    )
    args = parser.parse_args(argv)
    runs = []
    if args.append and args.output.is_file():
        asked = set(args.databases.split(","))
        earlier = json.loads(args.output.read_text())["runs"]
        runs = [run for run in earlier if run["database"] not in asked]
    with tempfile.TemporaryDirectory(prefix="vigil-bench-storage-") as tmp:
        for kind in args.databases.split(","):
            frames = args.pg_frames if kind == "postgresql" else args.sqlite_frames
            runs.append(bench_database(kind, frames, args, Path(tmp)))
            print(json.dumps(runs[-1]), flush=True)
            write_results(args, runs)
    print(f"wrote {args.output}")
    return 0


def write_results(args, runs: list[dict]) -> None:
    """After each database, so that a later failure keeps the runs already measured."""
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(
        json.dumps(
            {
                "runs": runs,
                "arguments": {
                    k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()
                },
                "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
                "note": "GENERATED history and GENERATED streaming robots (fixed skeletons); the "
                "training export reads the real URFD recordings. Policy defaults (30 days, "
                "alarm window 60 s before / 30 s after, labelled videos kept). The machine's 2 "
                "cores are shared with other engineers' jobs: see load_average_1min.",
            },
            indent=2,
        )
        + "\n"
    )


if __name__ == "__main__":
    raise SystemExit(main())
