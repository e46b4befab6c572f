"""How the agent runs its transports (robot_agent.agent.RobotAgent.produce): a GENERATED
transport is made before it starts, so the backend never sees a transport under way without
frames (a stalled stream, an offline robot) while the generator works."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

from robot_agent.agent import AgentOptions, RobotAgent
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.source_factory import generated_transports
from vigil.classes import TransportMode
from vigil.runtime import FrameClassifier

from .tiny_model import write_upright_model


def test_a_generated_transport_starts_once_every_frame_is_made(tmp_path):
    model = write_upright_model(tmp_path / "m1", "upright-1")
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING, FrameClassifier.from_dir(model)
    )
    steps: list[str] = []
    (plan,) = generated_transports(seed=3, count=1, duration_s=2.0, n_people=1)
    assert plan.materialise

    source = plan.observations

    def observations():
        for observation in source:
            steps.append("frame made")
            yield observation

    plan.observations = observations()  # type: ignore[misc]
    start = pipeline.start_transport

    def start_transport(*args, **kwargs):
        steps.append("transport started")
        return start(*args, **kwargs)

    pipeline.start_transport = start_transport  # type: ignore[method-assign]
    options = AgentOptions(url="ws://x/ws/robot", speed=0)
    agent = RobotAgent("robot-a", "token", pipeline, iter([plan]), options, tmp_path / "models")
    with ThreadPoolExecutor(1) as pool:  # a loop of its own (see test_agent_assignments)
        pool.submit(asyncio.run, agent.produce()).result()
    made = steps.count("frame made")
    assert made > 30
    assert steps == ["frame made"] * made + ["transport started"]
    assert agent.frames == made and agent.source_done.is_set()
