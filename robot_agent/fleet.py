"""A simulated fleet: N robots in one process, each streaming GENERATED transports that include
falls, with the real classifier (a model directory) or the generator's ground truth."""

from __future__ import annotations

import asyncio
import json
import logging
from dataclasses import dataclass
from pathlib import Path

from robot_agent.client import Backoff, LocalAlarm, RobotClient
from robot_agent.models import ModelManager
from robot_agent.outbox import Outbox
from robot_agent.pipeline import FramePipeline
from robot_agent.runner import simulator_locomotions, stream
from robot_agent.sources.simulator import simulated_transports
from vigil.classes import TransportMode
from vigil.runtime import FrameClassifier

log = logging.getLogger("robot_agent.fleet")


@dataclass
class FleetRobot:
    robot_id: str
    pipeline: FramePipeline
    client: RobotClient
    alarm: LocalAlarm
    outbox: Outbox


def read_tokens(path: Path) -> dict[str, str]:
    try:
        tokens = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"tokens_file: cannot read {path}: {error}") from error
    if not isinstance(tokens, dict) or not tokens:
        raise ValueError(f"tokens_file: {path} must hold a JSON object robot id -> token")
    return {str(k): str(v) for k, v in tokens.items()}


async def run_fleet(
    backend_url: str,
    tokens: dict[str, str],
    robots: int,
    state_dir: Path,
    model_dir: Path | None = None,
    ground_truth: bool = False,
    speed: float = 1.0,
    transports: int | None = None,
    duration_s: float = 30.0,
    n_people: int = 1,
    stop: asyncio.Event | None = None,
) -> dict[str, int]:
    """Returns frames streamed per robot."""
    if model_dir is None and not ground_truth:
        raise ValueError("model_dir: give a model directory, or ground_truth to stream labels")
    ids = sorted(tokens, key=_natural)[:robots]
    if len(ids) < robots:
        raise ValueError(f"tokens_file: holds {len(ids)} robots, {robots} requested")
    stop = stop or asyncio.Event()
    mode = TransportMode.WALKING
    fleet: list[FleetRobot] = []
    for robot_id in ids:
        models = None
        if not ground_truth:
            classifier = FrameClassifier.from_dir(model_dir)
            mode = classifier.manifest.mode
            models = ModelManager(state_dir / robot_id / "models", classifier)
        outbox = Outbox(state_dir / robot_id / "outbox.sqlite")
        fleet.append(
            FleetRobot(
                robot_id,
                FramePipeline(outbox, models, mode, use_ground_truth=ground_truth),
                RobotClient(
                    backend_url,
                    robot_id,
                    tokens[robot_id],
                    outbox,
                    models,
                    backoff=Backoff(cap_s=5.0),
                ),
                LocalAlarm(robot_id),
                outbox,
            )
        )
    log.info(
        "simulated fleet of %d robots (GENERATED transports, %s) -> %s",
        len(fleet),
        "ground truth" if ground_truth else f"model {model_dir}",
        backend_url,
    )
    locomotions = simulator_locomotions(mode) if ground_truth else simulator_locomotions(mode)
    clients = [asyncio.create_task(r.client.run(stop)) for r in fleet]

    async def one(index: int, robot: FleetRobot) -> int:
        sources = (
            (loc.transport_mode if mode is not TransportMode.COMBINED else mode, obs)
            for loc, obs in simulated_transports(
                index + 1, locomotions, duration_s, n_people, transports
            )
        )
        frames = await stream(robot.pipeline, robot.client, robot.alarm, sources, stop, speed)
        while len(robot.outbox) and not stop.is_set():
            await asyncio.sleep(0.1)
        return frames

    try:
        counts = await asyncio.gather(*(one(i, r) for i, r in enumerate(fleet)))
        return dict(zip(ids, counts, strict=True))
    finally:
        stop.set()
        await asyncio.gather(*clients, return_exceptions=True)
        for robot in fleet:
            robot.outbox.close()


def _natural(robot_id: str) -> tuple:
    head = robot_id.rstrip("0123456789")
    tail = robot_id[len(head) :]
    return (head, int(tail) if tail else -1)
