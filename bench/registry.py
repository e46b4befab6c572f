"""`python -m bench.registry`: the worker and registry on real data and real databases.
Writes bench/results/registry.json.

- queue: N jobs claimed and finished by two concurrent workers (own connections), on SQLite and
  on PostgreSQL (FOR UPDATE SKIP LOCKED): jobs per second, and jobs claimed twice (must be 0).
- retrain: the retrain job (rf-default, the same configuration as `train-default`) on the URFD
  training split (56 real recordings) in the database, evaluated on the held-out gold split (6
  falls, 8 daily activities, real URFD data): job seconds, Table 3 columns, per-frame latency,
  and the promotion gate's decision with default settings.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import threading
import time
import uuid
from pathlib import Path

from sqlalchemy import create_engine, text

from backend.db import make_engine, make_session_factory, transaction
from backend.jobs import queue
from backend.labelling.importers.urfd import import_urfd
from backend.migrate import upgrade
from backend.models.jobs import Job, JobKind, JobStatus
from backend.models.registry import ModelVersion
from backend.models.videos import Split
from backend.registry.gate import gate_report
from backend.settings import Settings
from worker.bootstrap import urfd_split
from worker.runner import Worker
from worker.settings import WorkerSettings
from worker.training.specs import DEFAULT

RESULTS = Path(__file__).resolve().parent / "results" / "registry.json"
PG_ADMIN_URL = os.environ.get(
    "VIGIL_TEST_PG_ADMIN_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)


def _postgres() -> tuple[str, callable] | None:
    name = f"vigil_bench_{uuid.uuid4().hex[:8]}"
    try:
        admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}"'))
    except Exception as error:  # no server: the SQLite figures still stand
        print(f"PostgreSQL unavailable ({error.__class__.__name__}); skipping it")
        return None

    def drop() -> None:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()

    return PG_ADMIN_URL.rsplit("/", 1)[0] + f"/{name}", drop


def bench_queue(url: str, jobs: int) -> dict:
    upgrade(url)
    engines = [make_engine(url) for _ in range(3)]
    factories = [make_session_factory(e) for e in engines]
    with transaction(factories[2]) as session:
        for i in range(jobs):
            queue.enqueue(session, JobKind.EVALUATE, {"model_version_id": i})
    claimed: dict[str, list[int]] = {"a": [], "b": []}
    barrier = threading.Barrier(2)

    def work(name: str, factory) -> None:
        barrier.wait()
        while (claim := queue.claim(factory, name)) is not None:
            claimed[name].append(claim.id)
            queue.finish(factory, claim.id, name, JobStatus.SUCCEEDED, "ok")

    threads = [
        threading.Thread(target=work, args=(n, f)) for n, f in zip("ab", factories[:2], strict=True)
    ]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    seconds = time.perf_counter() - start
    everything = claimed["a"] + claimed["b"]
    for engine in engines:
        engine.dispose()
    return {
        "jobs": jobs,
        "seconds": round(seconds, 3),
        "jobs_per_s": round(jobs / seconds, 1),
        "claimed_by_worker": {k: len(v) for k, v in claimed.items()},
        "claimed_twice": len(everything) - len(set(everything)),
        "never_claimed": jobs - len(set(everything)),
    }


def bench_retrain(workdir: Path) -> dict:
    url = f"sqlite:///{workdir / 'retrain.db'}"
    upgrade(url)
    engine = make_engine(url)
    factory = make_session_factory(engine)
    train, gold = urfd_split()
    with transaction(factory) as session:
        import_urfd(session, names=train, split=Split.TRAIN)
        import_urfd(session, names=gold, split=Split.TEST)
        job_id = queue.enqueue(session, JobKind.RETRAIN, {"spec": DEFAULT.name}).id
    settings = WorkerSettings(
        database_url=url, model_store_dir=workdir / "models", worker_id="bench"
    )
    start = time.perf_counter()
    Worker(settings, factory, sweeps=[]).run_once()
    seconds = time.perf_counter() - start
    with factory() as session:
        job = session.get(Job, job_id)
        if job.status != JobStatus.SUCCEEDED:
            raise RuntimeError(f"retrain failed: {job.message}\n{job.log}")
        model = session.get(ModelVersion, job.result["model_version_id"])
        backend = Settings()
        gate = gate_report(model, backend.gate_false_alarm_budget, backend.gate_latency_ms)
        gold_metrics = model.metrics["gold"]
        result = {
            "data": "URFD (real): 56 training recordings in the database; gold = 14 held-out "
            "recordings (split 'test')",
            "training_recordings": len(train),
            "gold_recordings": gold,
            "job_seconds": round(seconds, 1),
            "model_version": model.version,
            "hyperparameters": model.lineage["hyperparameters"],
            "threshold": model.manifest["threshold"],
            "delay_ms": model.manifest["delay_ms"],
            "gold": {
                k: v
                for k, v in gold_metrics.items()
                if k not in ("events", "sequences", "fold_operating_points")
            },
            "gold_events": gold_metrics["events"],
            "latency": model.metrics["latency"],
            "gate": {
                "passed": gate["passed"],
                "checks": gate["checks"],
                "warnings": gate["warnings"],
            },
        }
    engine.dispose()
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=300)
    parser.add_argument("--skip-retrain", action="store_true")
    args = parser.parse_args()
    machine = {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    out: dict = {"benchmark": "registry", "machine": machine}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        out["queue"] = {"sqlite": bench_queue(f"sqlite:///{tmp / 'queue.db'}", args.jobs)}
        pg = _postgres()
        if pg is not None:
            url, drop = pg
            try:
                out["queue"]["postgresql"] = bench_queue(url, args.jobs)
            finally:
                drop()
        print(json.dumps(out["queue"], indent=1))
        if not args.skip_retrain:
            out["retrain"] = bench_retrain(tmp)
            print(
                json.dumps(
                    {k: out["retrain"][k] for k in ("job_seconds", "gold", "gate")}, indent=1
                )
            )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
