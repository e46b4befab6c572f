"""How the agent answers `assign_model` without a network: a production assignment carrying
`stop_shadow` (protocol 1 extension) stops the shadow model; one without it leaves it running."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

from robot_agent.agent import AgentOptions, RobotAgent
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from vigil.classes import TransportMode
from vigil.model_file import read_manifest
from vigil.protocol import ModelAssignment
from vigil.runtime import FrameClassifier

from .tiny_model import write_upright_model


def _agent(tmp_path) -> RobotAgent:
    production = write_upright_model(tmp_path / "m1", "upright-1")
    candidate = write_upright_model(tmp_path / "c1", "candidate-1", threshold=0.9)
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING, FrameClassifier.from_dir(production)
    )
    pipeline.set_shadow(FrameClassifier.from_dir(candidate))
    return RobotAgent(
        "robot-a",
        "token",
        pipeline,
        iter([]),
        AgentOptions(url="ws://x/ws/robot"),
        tmp_path / "models",
    )


def _run(coroutine) -> None:
    """asyncio.run in a thread of its own: a browser test's sync Playwright may have left an
    event loop running in the main thread."""
    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, coroutine).result()


def _production(tmp_path, **extra) -> ModelAssignment:
    manifest, _ = read_manifest(tmp_path / "m1")
    return ModelAssignment(
        version="upright-1",
        url="http://127.0.0.1:9/api/robot/models/upright-1/file",
        sha256=manifest.sha256,
        manifest=manifest.model_dump(mode="json"),
        **extra,
    )


def test_a_production_assignment_with_stop_shadow_stops_the_shadow_model(tmp_path):
    agent = _agent(tmp_path)
    _run(agent.on_assignment(_production(tmp_path, stop_shadow=True)))
    assert agent.pipeline.shadow is None
    assert agent.pipeline.running_model == "upright-1"  # already running: nothing fetched


def test_a_production_assignment_without_stop_shadow_keeps_the_shadow_model(tmp_path):
    agent = _agent(tmp_path)
    _run(agent.on_assignment(_production(tmp_path)))
    assert agent.pipeline.shadow.manifest.version == "candidate-1"
    assert agent.pipeline.running_model == "upright-1"
