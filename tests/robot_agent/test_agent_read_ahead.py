"""The agent reads a recording or camera one frame ahead: the next frame's pose estimation (in
the source's thread) runs while the current frame goes through the frame path, so a robot keeps
real time while the slower of the two fits between frames, not their sum (docs/robot_agent.md)."""

from __future__ import annotations

import asyncio
import threading
from concurrent.futures import ThreadPoolExecutor

from robot_agent.agent import AgentOptions, RobotAgent, TransportPlan
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from vigil.classes import TransportMode
from vigil.observation import Observation

FRAMES = 5


def test_the_next_frame_is_read_while_this_one_is_processed(tmp_path):
    reading = [threading.Event() for _ in range(FRAMES + 1)]  # reading[i]: frame i requested

    def source():
        for i in range(FRAMES):
            reading[i].set()
            yield Observation(i / 30.0, [], i)
        reading[FRAMES].set()  # asked for one more: the end of the recording

    pipeline = Pipeline(Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING)
    processed, overlapped = [], []
    process = pipeline.process

    def process_after_the_next_read_started(observation):
        # Without reading ahead nobody asks for the next frame before this returns: no overlap.
        overlapped.append(reading[observation.index + 1].wait(timeout=5))
        processed.append(observation.index)
        return process(observation)

    pipeline.process = process_after_the_next_read_started
    plans = iter([TransportPlan(source())])
    options = AgentOptions(url="ws://x/ws/robot", speed=0)
    agent = RobotAgent("robot-a", "token", pipeline, plans, options, tmp_path / "models")
    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, agent.produce()).result(timeout=60)
    assert processed == list(range(FRAMES))
    assert overlapped == [True] * FRAMES
    assert agent.frames == FRAMES
