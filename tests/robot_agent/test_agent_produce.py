"""How the agent runs its transports (robot_agent.agent.RobotAgent.produce): a GENERATED
transport is made before it starts, so the backend never sees a transport under way without
frames (a stalled stream, an offline robot) while the generator works; and a robot behind real
time still lets its link run between frames."""

from __future__ import annotations

import asyncio
import time
from concurrent.futures import ThreadPoolExecutor

from robot_agent.agent import AgentOptions, RobotAgent, TransportPlan
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.source_factory import generated_transports
from vigil.classes import TransportMode
from vigil.observation import Observation
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


def test_a_robot_behind_real_time_still_lets_its_link_run(tmp_path):
    """A frame path slower than real time (a loaded machine; three simulated robots in one
    process) must not starve the event loop: the link's send loop and heartbeats run between
    frames. Without it the backend saw no frame and no heartbeat for a whole transport and
    raised stream_stalled and robot_offline on nearly every transport of `make run`."""
    frames = 30
    observations = [Observation(i / 30.0, [], i) for i in range(frames)]
    pipeline = Pipeline(Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING)
    process = pipeline.process

    def slow_process(observation):
        time.sleep(0.05)  # 50 ms a frame at 30 frames/s: 1.5 times slower than real time
        return process(observation)

    pipeline.process = slow_process  # type: ignore[method-assign]
    plan = TransportPlan(iter(observations), materialise=True)  # as a GENERATED transport
    options = AgentOptions(url="ws://x/ws/robot", speed=1.0)
    agent = RobotAgent("robot-a", "token", pipeline, iter([plan]), options, tmp_path / "models")
    ticks: list[float] = []

    async def link_like_task() -> None:
        while not agent.source_done.is_set():
            ticks.append(time.monotonic())
            await asyncio.sleep(0.01)

    async def both() -> None:
        await asyncio.gather(agent.produce(), link_like_task())

    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, both()).result(timeout=60)
    assert agent.frames == frames
    gaps = [b - a for a, b in zip(ticks, ticks[1:], strict=False)]
    # The whole transport takes about 1.5 s; the other task must run at least every few frames.
    assert len(ticks) >= 10 and max(gaps) < 0.3, (len(ticks), max(gaps))
