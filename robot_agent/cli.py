"""`vigil-robot`: run the robot agent (``run``) or a simulated fleet (``simulate``)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys
from pathlib import Path

from pydantic import ValidationError

from robot_agent.client import FatalConnectionError
from robot_agent.config import RobotSettings, describe_error, load_settings

log = logging.getLogger("robot_agent")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="vigil-robot", description=__doc__)
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="stream one robot's camera data to the backend")
    run.add_argument("--config", type=Path, help="TOML or JSON file (a [robot] table)")
    for name, field in RobotSettings.model_fields.items():
        flag = "--" + name.replace("_", "-")
        if field.annotation is bool:
            run.add_argument(
                flag, dest=name, action="store_true", default=None, help=field.description
            )
        else:
            run.add_argument(flag, dest=name, help=field.description)
    sim = sub.add_parser("simulate", help="a simulated fleet streaming GENERATED transports")
    sim.add_argument("--backend", required=True, help="ws://host:port/ws/robot")
    sim.add_argument("--robots", type=int, default=3)
    sim.add_argument("--tokens-file", type=Path, required=True, help="JSON robot id -> token")
    sim.add_argument("--model-dir", type=Path, help="model directory (manifest.json + onnx)")
    sim.add_argument(
        "--ground-truth",
        action="store_true",
        help="stream the generator's ground-truth decisions instead of a model",
    )
    sim.add_argument("--state-dir", type=Path, default=Path("var/fleet"))
    sim.add_argument("--speed", type=float, default=1.0, help="1 = real time")
    sim.add_argument("--transports", type=int, help="per robot; default: endless")
    sim.add_argument("--duration", type=float, default=30.0, help="seconds per transport")
    sim.add_argument("--people", type=int, default=1, help="people in view (1-5)")
    sim.add_argument("--log-level", default="INFO")
    return parser


def _logging(level: str) -> None:
    logging.basicConfig(
        level=level.upper(), format="%(asctime)s %(name)s: %(message)s", datefmt="%H:%M:%S"
    )


def _with_signals(coro_factory):
    async def main():
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        return await coro_factory(stop)

    return asyncio.run(main())


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("run", "simulate", "-h", "--help"):
        argv.insert(0, "run")
    args = _parser().parse_args(argv)
    if args.command == "simulate":
        return _simulate(args)
    overrides = {k: v for k, v in vars(args).items() if k not in ("command", "config")}
    try:
        settings = load_settings(args.config, overrides)
    except ValidationError as error:
        print(f"vigil-robot: bad configuration: {describe_error(error)}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as error:
        print(f"vigil-robot: bad configuration: config: {error}", file=sys.stderr)
        return 2
    _logging(settings.log_level)
    if not settings.token:
        print(
            "vigil-robot: bad configuration: token: this robot's token is required", file=sys.stderr
        )
        return 2
    if settings.model_dir is None and not settings.ground_truth:
        print(
            "vigil-robot: bad configuration: model_dir: give a model directory (or "
            "--ground-truth with the simulator)",
            file=sys.stderr,
        )
        return 2
    from robot_agent.runner import run_robot

    log.info(
        "robot %s: %s source, %s mode, backend %s",
        settings.robot_id,
        settings.source.value,
        settings.mode.value,
        settings.backend_url,
    )
    try:
        _with_signals(lambda stop: run_robot(settings, stop))
    except FatalConnectionError as error:
        print(f"vigil-robot: stopped: {error}", file=sys.stderr)
        return 3
    except (ValueError, OSError) as error:
        print(f"vigil-robot: stopped: {error}", file=sys.stderr)
        return 2
    return 0


def _simulate(args) -> int:
    _logging(args.log_level)
    from robot_agent.fleet import read_tokens, run_fleet

    try:
        tokens = read_tokens(args.tokens_file)
        if args.model_dir is None and not args.ground_truth:
            raise ValueError("model_dir: give --model-dir, or --ground-truth")
        if not 1 <= args.people <= 5:
            raise ValueError("people: must be 1-5")
        counts = _with_signals(
            lambda stop: run_fleet(
                args.backend,
                tokens,
                args.robots,
                args.state_dir,
                args.model_dir,
                args.ground_truth,
                args.speed,
                args.transports,
                args.duration,
                args.people,
                stop,
            )
        )
    except FatalConnectionError as error:
        print(f"vigil-robot simulate: stopped: {error}", file=sys.stderr)
        return 3
    except (ValueError, OSError) as error:
        print(f"vigil-robot simulate: bad configuration: {error}", file=sys.stderr)
        return 2
    log.info("fleet finished: %s", counts)
    return 0


if __name__ == "__main__":
    sys.exit(main())
