"""A model on the robot's disk whose file is not the registry's is refused (issue 18, item 5):
the file and its local manifest were both replaced by an always-Normal model. It is refused at
start (RUNNING notes the registry's sha256), after the welcome (the backend sends the registry's
sha256) and at an assignment of the version it runs; it never decides a frame, the verified
keypoints-only fallback decides instead (or nothing), and a detection_status tells the nurse
board why. Without a network: the agent's handlers are called directly."""

from __future__ import annotations

import asyncio
import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from robot_agent.agent import AgentOptions, RobotAgent
from robot_agent.config import load_settings
from robot_agent.models import RUNNING_FILE, remember_running
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.runner import starting_model
from vigil.classes import TransportMode
from vigil.model_file import read_manifest
from vigil.protocol import DetectionStatus, ModelAssignment, Welcome
from vigil.runtime import FrameClassifier

from .test_pipeline import FallSource, frames_of
from .tiny_model import write_upright_model

VERSION = "upright-7"


def genuine_and_tampered(models: Path) -> tuple[str, Path]:
    """The registry's upright-7 (its sha256), and the robot's copy replaced, manifest and all,
    by an always-Normal graph of the same version: it verifies against its local manifest."""
    directory = write_upright_model(models / VERSION, VERSION)
    genuine = read_manifest(directory)[0].sha256
    write_upright_model(directory, VERSION, always_normal=True)
    assert read_manifest(directory)[0].sha256 != genuine
    FrameClassifier.from_dir(directory)  # the local check alone passes
    return genuine, directory


def statuses(outbox: Outbox) -> list[DetectionStatus]:
    messages = [json.loads(m.text) for m in outbox.pending(limit=100_000) if m.seq is None]
    return [DetectionStatus.model_validate(m) for m in messages if m["type"] == "detection_status"]


def run(coroutine) -> None:
    with ThreadPoolExecutor(1) as pool:  # a browser test may have left a loop in this thread
        pool.submit(asyncio.run, coroutine).result()


def agent_running_tampered(tmp_path, with_fallback: bool) -> tuple[RobotAgent, str, str | None]:
    models = tmp_path / "robot-models"
    genuine, directory = genuine_and_tampered(models)
    remember_running(models, VERSION)  # as an older agent wrote it: no sha256 to check at start
    fallback = fallback_sha = None
    if with_fallback:
        fallback = FrameClassifier.from_dir(
            write_upright_model(tmp_path / "kp-1", "kp-1", feature_set="keypoints")
        )
        fallback_sha = fallback.sha256
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"),
        TransportMode.WALKING,
        FrameClassifier.from_dir(directory),
        fallback=fallback,
    )
    agent = RobotAgent(
        "robot-a", "token", pipeline, iter([]), AgentOptions(url="ws://x/ws/robot"), models
    )
    return agent, genuine, fallback_sha


def decide_a_fall(pipeline: Pipeline) -> list[dict]:
    pipeline.start_transport("t-1", ts=1_700_000_000.0)
    for observation in FallSource():
        pipeline.process(observation)
    return frames_of(pipeline.outbox)


def test_the_hello_tells_the_sha256_of_the_files_the_robot_runs(tmp_path):
    agent, _, fallback_sha = agent_running_tampered(tmp_path, with_fallback=True)
    tampered = read_manifest(tmp_path / "robot-models" / VERSION)[0].sha256
    assert agent.pipeline.loaded_models() == {
        "running_sha256": tampered,
        "fallback_model": "kp-1",
        "fallback_sha256": fallback_sha,
    }


def test_after_the_welcome_a_tampered_model_is_refused_and_the_fallback_decides(tmp_path):
    agent, genuine, fallback_sha = agent_running_tampered(tmp_path, with_fallback=True)
    agent._on_welcome(
        Welcome(
            robot_id="robot-a", last_seq=None, model_sha256={VERSION: genuine, "kp-1": fallback_sha}
        )
    )
    pipeline = agent.pipeline
    assert pipeline.running_model == "kp-1"
    assert pipeline.running_sha256 == fallback_sha  # what the heartbeat reports
    assert "refused" in agent.link.model_error and genuine in agent.link.model_error
    assert not (agent.models_dir / RUNNING_FILE).exists()  # a restart will not start with it
    (status,) = statuses(pipeline.outbox)
    assert status.degraded and status.missing_inputs == []
    assert status.assigned_model == VERSION and status.running_model == "kp-1"
    assert "sha256" in status.reason and "keypoints-only fallback kp-1" in status.reason
    # The tampered model decides no frame; the fallback sees the fall.
    frames = decide_a_fall(pipeline)
    assert {f["model_version"] for f in frames} == {"kp-1"}
    assert any(f["decision"] == "emergency" for f in frames)


def test_without_a_verified_fallback_nothing_decides_and_the_status_says_so(tmp_path):
    agent, genuine, _ = agent_running_tampered(tmp_path, with_fallback=True)
    # The fallback's own file is not the registry's either: it is not used.
    registry = {VERSION: genuine, "kp-1": "0" * 64}
    agent._on_welcome(Welcome(robot_id="robot-a", last_seq=None, model_sha256=registry))
    assert agent.pipeline.running_model is None and agent.pipeline.fallback is None
    (status,) = statuses(agent.pipeline.outbox)
    assert status.running_model is None and "no model decides" in status.reason
    assert all(f["decision"] is None for f in decide_a_fall(agent.pipeline))


def test_an_assignment_of_the_running_version_with_another_sha256_refuses_it(tmp_path):
    agent, genuine, _ = agent_running_tampered(tmp_path, with_fallback=False)
    manifest, _ = read_manifest(tmp_path / "robot-models" / VERSION)
    assignment = ModelAssignment(
        version=VERSION,
        url="http://127.0.0.1:9/api/robot/models/upright-7/file",
        sha256=genuine,
        manifest=manifest.model_dump(mode="json"),
    )
    run(agent.on_assignment(assignment))  # the download of the genuine file fails here
    assert agent.pipeline.running_model is None
    assert "refused" in statuses(agent.pipeline.outbox)[0].reason
    assert agent.link.model_error  # refusal, then the failed download: reported either way


def test_the_registry_not_knowing_a_version_leaves_it_running(tmp_path):
    agent, _, _ = agent_running_tampered(tmp_path, with_fallback=False)
    agent._on_welcome(Welcome(robot_id="robot-a", last_seq=None, model_sha256={}))
    assert agent.pipeline.running_model == VERSION and statuses(agent.pipeline.outbox) == []


def test_a_tampered_model_is_refused_at_start_against_the_noted_registry_sha256(tmp_path):
    models = tmp_path / "robot-models"
    genuine, _ = genuine_and_tampered(models / "robot-a")
    remember_running(models / "robot-a", VERSION, genuine)  # noted with the assignment
    shipped = write_upright_model(tmp_path / "shipped", "upright-1")
    settings = load_settings(
        None, robot_id="robot-a", model_dir=str(shipped), models_dir=str(models)
    )
    classifier, refusal = starting_model(settings, "robot-a")
    assert classifier.version == "upright-1"  # the configured model, not the tampered one
    assert refusal.version == VERSION and genuine in refusal.reason
    # Untampered, the same noted sha256 starts it.
    write_upright_model(models / "robot-a" / VERSION, VERSION)
    classifier, refusal = starting_model(settings, "robot-a")
    assert classifier.version == VERSION and refusal is None
