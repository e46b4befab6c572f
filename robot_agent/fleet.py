"""`vigil-robot simulate`: several robots in one process (asyncio), each with its own outbox,
link and pipeline, streaming GENERATED transports (walking and rollator patients, bystanders)
at a ward's pace: falls, Pause situations and fall look-alikes at `falls_per_hour`,
`pauses_per_hour` and `lookalikes_per_hour` per robot (default one fall per robot per 15 min),
routine movement otherwise.

Decisions: with --model-dir every robot classifies with that model; without it a robot streams
the generator's ground truth, marked model_version 'generated-ground-truth' (no threshold, no
delay), until the backend assigns it a model, which it then downloads, verifies and runs.
"""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

from robot_agent.agent import RobotAgent
from robot_agent.client import LinkFatal
from robot_agent.config import AgentSettings, ConfigError
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.runner import agent_options, initial_classifier, starting_model
from robot_agent.source_factory import EventRates, generated_transports
from vigil.classes import TransportMode

log = logging.getLogger(__name__)


class Fleet:
    def __init__(self, agents: list[RobotAgent]) -> None:
        self.agents = agents

    async def run(self) -> None:
        results = await asyncio.gather(*(a.run() for a in self.agents), return_exceptions=True)
        for agent, result in zip(self.agents, results, strict=True):
            if isinstance(result, LinkFatal):
                log.error("robot %s stopped: %s", agent.robot_id, result)
            elif isinstance(result, BaseException):
                log.error("robot %s failed: %r", agent.robot_id, result)


def _locomotion(mode: TransportMode, number: int) -> str:
    if mode == TransportMode.WHEELCHAIR:
        return "wheelchair"
    if mode == TransportMode.COMBINED:
        return ("walking", "rollator", "wheelchair")[number % 3]
    return ("walking", "rollator")[number % 2]


def build_fleet(
    settings: AgentSettings,
    tokens: dict[str, str],
    robots: int,
    transports: int | None,
    outbox_dir: Path,
) -> Fleet:
    if robots > len(tokens):
        raise ConfigError(
            f"robots: {robots} requested but the tokens file has {len(tokens)} robots"
        )
    if transports is not None:
        settings = settings.model_copy(update={"exit_when_done": True})
    initial_classifier(settings)  # check --model-dir once, with a clear message
    agents = []
    for number, robot_id in enumerate(sorted(tokens)[:robots]):
        classifier, refusal = starting_model(settings, robot_id)  # one per robot: stream state
        pipeline = Pipeline(
            Outbox(outbox_dir / f"{robot_id}.sqlite", settings.outbox_budget_bytes),
            settings.mode,
            classifier,
            ground_truth_fallback=True,
            available_inputs=["keypoints", "depth", "floor"],  # the generator knows them all
        )
        if refusal is not None:
            pipeline.report_refusal(refusal.version, refusal.reason)
        plans = generated_transports(
            seed=settings.seed + 1000 * number,
            locomotion=_locomotion(settings.mode, number),
            count=transports,
            n_people=settings.people,
            duration_s=settings.duration_s,
            patient_prefix=f"GEN-{number + 1}",
            rates=EventRates(
                settings.falls_per_hour, settings.pauses_per_hour, settings.lookalikes_per_hour
            ),
        )
        agents.append(
            RobotAgent(
                robot_id,
                tokens[robot_id],
                pipeline,
                plans,
                _own_socket(agent_options(settings), robot_id),
                settings.models_dir / robot_id,
            )
        )
        log.info(
            "robot %s: %s transports of GENERATED patients, decisions from %s",
            robot_id,
            _locomotion(settings.mode, number),
            pipeline.running_model,
        )
    return Fleet(agents)


def _own_socket(options, robot_id: str):
    """One local command socket per simulated robot: `<stem>-<robot_id><suffix>`."""
    path = options.local_socket
    if path is not None:
        options.local_socket = path.with_name(f"{path.stem}-{robot_id}{path.suffix}")
    return options
