"""vigil-worker: run the job queue; import URFD recordings; queue jobs from the shell.

vigil-worker run                              # claim and run jobs until Ctrl-C
vigil-worker import-urfd --split test --names fall-01,adl-01
vigil-worker enqueue retrain '{"spec": "rf-default"}'
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
from pathlib import Path

from backend.db import make_engine, make_session_factory, transaction
from backend.models.jobs import JobKind
from backend.models.videos import Split
from worker.settings import WorkerSettings


def _names(value: str) -> list[str]:
    return [n.strip() for n in value.split(",") if n.strip()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="vigil-worker", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="claim and run jobs until stopped")
    run.add_argument("--once", action="store_true", help="run at most one job, then exit")
    imp = commands.add_parser("import-urfd", help="store URFD sequences as labelled recordings")
    imp.add_argument("--split", choices=[s.value for s in Split], required=True)
    imp.add_argument("--names", type=_names, required=True, help="e.g. fall-01,adl-01")
    boot = commands.add_parser("bootstrap", help="first run: URFD split, default model, retrain")
    boot.add_argument("--default-model", type=Path, default=None, help="model directory")
    enq = commands.add_parser("enqueue", help="queue a job")
    enq.add_argument("kind", choices=[k.value for k in JobKind])
    enq.add_argument("params", nargs="?", default="{}", help="JSON object")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    settings = WorkerSettings()

    if args.command == "run":
        from worker.runner import Worker

        worker = Worker(settings)
        signal.signal(signal.SIGTERM, lambda *_: worker.stop())
        try:
            if args.once:
                worker.run_once()
            else:
                worker.run_forever()
        except KeyboardInterrupt:
            worker.stop()
        return 0

    engine = make_engine(settings.database_url)
    try:
        with transaction(make_session_factory(engine)) as session:
            if args.command == "bootstrap":
                from worker.bootstrap import bootstrap

                for line in bootstrap(session, args.default_model):
                    print(line)
            elif args.command == "import-urfd":
                from backend.labelling.importers.urfd import import_urfd

                try:
                    videos = import_urfd(session, names=args.names, split=Split(args.split)).videos
                except KeyError as error:
                    print(f"vigil-worker: --names: {error.args[0]}", file=sys.stderr)
                    return 2
                print(f"{len(videos)} URFD recordings in split {args.split}")
            else:
                from backend.jobs import queue

                try:
                    params = json.loads(args.params)
                except json.JSONDecodeError as error:
                    print(f"vigil-worker: params is not JSON: {error}", file=sys.stderr)
                    return 2
                if not isinstance(params, dict):
                    print("vigil-worker: params must be a JSON object", file=sys.stderr)
                    return 2
                from backend.jobs.params import validate

                try:
                    validate(JobKind(args.kind), params)
                except ValueError as error:
                    print(f"vigil-worker: {error}", file=sys.stderr)
                    return 2
                job = queue.enqueue(session, JobKind(args.kind), params)
                session.flush()
                print(f"queued job {job.id} ({args.kind})")
    finally:
        engine.dispose()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
