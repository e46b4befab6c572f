"""`vigil-robot`: the robot agent.

    vigil-robot run --config robot.toml [flags]       one robot from a keypoint source
    vigil-robot run --source rosbag --source-path BAG [--record-bag OUT]
                                                      one robot on a ROS 2 recording; OUT: a
                                                      copy of it plus its decisions
    vigil-robot simulate --backend URL --robots 3 --tokens-file var/robot_tokens.json
                                                      a fleet of robots on GENERATED transports
    vigil-robot reset --config robot.toml             reset this robot's emergency stop (local
                                                      socket; audited on the server)

Settings come from the TOML config file, then VIGIL_ROBOT_* environment variables, then flags.
Bad configuration exits with code 2 and a message naming the field; a robot the backend refuses
(token, protocol) exits with code 1.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import sys
from pathlib import Path

from robot_agent.config import AgentSettings, ConfigError, SourceKind, load_settings, read_tokens

log = logging.getLogger("vigil.robot")
EXIT_BAD_CONFIG = 2
EXIT_REFUSED = 1

# flag -> setting; every flag is a plain string so that the settings class checks (and names)
# the value, whatever its source.
SHARED_FLAGS = {
    "--backend": "backend_url",
    "--mode": "mode",
    "--model-dir": "model_dir",
    "--fallback-model-dir": "fallback_model_dir",
    "--models-dir": "models_dir",
    "--outbox-budget-bytes": "outbox_budget_bytes",
    "--heartbeat-s": "heartbeat_s",
    "--batch-frames": "batch_frames",
    "--backoff-initial-s": "backoff_initial_s",
    "--backoff-max-s": "backoff_max_s",
    "--alarm-after-s": "alarm_after_s",
    "--alarm-hook": "alarm_hook",
    "--pause-hold-s": "pause_hold_s",
    "--degraded-action": "degraded_action",
    "--patient-unseen-s": "patient_unseen_s",
    "--local-socket": "local_socket",
    "--speed": "speed",
    "--seed": "seed",
    "--duration-s": "duration_s",
    "--people": "people",
    "--log-level": "log_level",
}
RUN_FLAGS = {
    "--robot-id": "robot_id",
    "--token": "token",
    "--token-file": "token_file",
    "--source": "source",
    "--source-path": "source_path",
    "--depth-dir": "depth_dir",
    "--depth-scale-mm": "depth_scale_mm",
    "--crop": "crop",
    "--camera-mount": "camera_mount",
    "--scenario": "scenario",
    "--patient": "patient",
    "--location": "location",
    "--outbox": "outbox_path",
    "--rgb-topic": "rgb_topic",
    "--depth-topic": "depth_topic",
    "--camera-info-topic": "camera_info_topic",
    "--depth-tolerance-s": "depth_tolerance_s",
    "--camera-height-m": "camera_height_m",
    "--camera-pitch-deg": "camera_pitch_deg",
    "--record-bag": "record_bag",
}
SIMULATE_FLAGS = {
    "--falls-per-hour": "falls_per_hour",
    "--pauses-per-hour": "pauses_per_hour",
    "--lookalikes-per-hour": "lookalikes_per_hour",
}
SWITCHES = {"--loop": "loop", "--exit-when-done": "exit_when_done"}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="vigil-robot", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run one robot from a keypoint source")
    simulate = commands.add_parser("simulate", help="a fleet of robots on GENERATED transports")
    for sub in (run, simulate):
        sub.add_argument("--config", type=Path, help="TOML config file")
        for flag, field in SHARED_FLAGS.items():
            sub.add_argument(flag, dest=field, help=AgentSettings.model_fields[field].description)
        for flag, field in SWITCHES.items():
            sub.add_argument(
                flag,
                dest=field,
                action="store_true",
                default=None,
                help=AgentSettings.model_fields[field].description,
            )
    reset = commands.add_parser("reset", help="reset this robot's emergency stop (local socket)")
    reset.add_argument("--config", type=Path, help="TOML config file")
    reset.add_argument(
        "--local-socket",
        dest="local_socket",
        help=AgentSettings.model_fields["local_socket"].description,
    )
    for flag, field in RUN_FLAGS.items():
        run.add_argument(flag, dest=field, help=AgentSettings.model_fields[field].description)
    for flag, field in SIMULATE_FLAGS.items():
        simulate.add_argument(flag, dest=field, help=AgentSettings.model_fields[field].description)
    simulate.add_argument("--robots", default="3", help="number of robots (from the tokens file)")
    simulate.add_argument(
        "--tokens-file",
        dest="token_file",
        type=Path,
        help="JSON {robot_id: token}, as `backend.cli seed-demo` writes it",
    )
    simulate.add_argument(
        "--transports", default=None, help="transports per robot, then stop (default: endless)"
    )
    simulate.add_argument(
        "--outbox-dir",
        type=Path,
        default=Path("var/robot-outbox"),
        help="one outbox file per robot in this directory",
    )
    return parser


def _setup_logging(level: str) -> None:
    logging.basicConfig(
        level=level,
        format="%(asctime)s %(levelname)-7s %(message)s",
        datefmt="%H:%M:%S",
        stream=sys.stderr,
        force=True,
    )
    for noisy in ("websockets", "asyncio"):
        logging.getLogger(noisy).setLevel(logging.WARNING)


def _positive_int(name: str, value: str | None) -> int | None:
    if value is None:
        return None
    try:
        number = int(value)
    except ValueError:
        raise ConfigError(f"{name}: must be a whole number (got {value!r})") from None
    if number < 1:
        raise ConfigError(f"{name}: must be at least 1 (got {number})")
    return number


async def _run_until_signal(coroutine) -> None:
    task = asyncio.ensure_future(coroutine)
    loop = asyncio.get_running_loop()
    for signum in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError):
            loop.add_signal_handler(signum, task.cancel)
    with contextlib.suppress(asyncio.CancelledError):
        await task


def _reset(settings: AgentSettings) -> int:
    from robot_agent.controller_client import reset

    if settings.local_socket is None:
        raise ConfigError("local_socket: required for reset (the running agent's socket)")
    try:
        reply = reset(settings.local_socket)
    except (FileNotFoundError, ConnectionRefusedError, TimeoutError, OSError) as error:
        print(
            f"vigil-robot: local_socket {settings.local_socket}: no agent answers ({error})",
            file=sys.stderr,
        )
        return EXIT_REFUSED
    if reply.get("reset"):
        print(f"emergency stop reset; the robot is {reply['state']} (reported to the backend)")
        return 0
    print(
        f"vigil-robot: nothing reset: {reply.get('reason') or reply.get('error')}", file=sys.stderr
    )
    return EXIT_REFUSED


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    given = {
        k: v for k, v in vars(args).items() if k in AgentSettings.model_fields and v is not None
    }
    try:
        settings = load_settings(args.config, **given)
        if args.command == "reset":
            return _reset(settings)
        _setup_logging(settings.log_level)
        if args.command == "run":
            from robot_agent.runner import build_robot

            agent = build_robot(settings)
            coroutine = agent.run()
        else:
            from robot_agent.fleet import build_fleet

            robots = _positive_int("robots", args.robots)
            transports = _positive_int("transports", args.transports)
            if settings.token_file is None:
                raise ConfigError("tokens_file: required for simulate")
            fleet = build_fleet(
                settings, read_tokens(settings.token_file), robots, transports, args.outbox_dir
            )
            coroutine = fleet.run()
    except ConfigError as error:
        print(f"vigil-robot: {error}", file=sys.stderr)
        return EXIT_BAD_CONFIG
    from robot_agent.client import LinkFatal

    try:
        asyncio.run(_run_until_signal(coroutine))
    except LinkFatal as error:
        log.error("stopped: %s", error)
        return EXIT_REFUSED
    except Exception as error:
        log.exception("stopped by an unexpected error: %s", error)
        return EXIT_REFUSED
    log.info("stopped")
    return 0


__all__ = ["main", "SourceKind"]

if __name__ == "__main__":
    sys.exit(main())
