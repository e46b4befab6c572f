"""Model updates: verified by sha256, swapped between two frames, tampered files refused (the
old model keeps running), both directly and through the real backend's assign_model."""

from __future__ import annotations

import asyncio
import shutil
import time

import pytest

from backend.db import transaction
from backend.models.registry import ModelVersion
from backend.models.robots import Robot
from backend.process import BackendProcess
from robot_agent.client import Backoff, RobotClient
from robot_agent.models import ModelManager, ModelRefused
from robot_agent.outbox import Outbox
from robot_agent.pipeline import FramePipeline
from robot_agent.sources.simulator import _observations
from tests.registry_fixtures import derive_model
from tests.robot_agent.conftest import ROBOT_TOKEN
from vigil.model_file import read_manifest
from vigil.protocol import ModelAssignment
from vigil.runtime import FrameClassifier
from vigil.synthetic import generate_transport


def _assignment(model_dir, url="http://unused") -> tuple[ModelAssignment, bytes]:
    manifest, directory = read_manifest(model_dir)
    data = (directory / manifest.file).read_bytes()
    assignment = ModelAssignment(version=manifest.version, url=url, sha256=manifest.sha256,
                                 manifest=manifest.model_dump(mode="json"))  # fmt: skip
    return assignment, data


def test_tampered_model_refused_old_keeps_running_good_one_swaps_between_frames(
    trained_model_dir, tmp_path
):
    v2 = derive_model(trained_model_dir, tmp_path / "v2", "rf-test-2", threshold=0.5)
    manager = ModelManager(tmp_path / "store", FrameClassifier.from_dir(trained_model_dir))
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = FramePipeline(outbox, manager)
    pipeline.start_transport()
    frames = list(_observations(generate_transport("walking", seed=2, duration_s=3)))

    assignment, data = _assignment(v2)
    tampered = bytearray(data)
    tampered[len(tampered) // 2] ^= 0xFF
    with pytest.raises(ModelRefused, match="sha256 mismatch"):
        manager.install_bytes(assignment, read_manifest(v2)[0], bytes(tampered))
    assert "rf-test-2" in manager.last_refusal
    assert not (tmp_path / "store" / "rf-test-2").exists()
    pipeline.process(frames[0])
    assert manager.running_version == "rf-test-1"

    manager.install_bytes(assignment, read_manifest(v2)[0], data)
    assert manager.running_version == "rf-test-1"  # not in the middle of a frame
    versions = []
    for obs in frames[1:4]:
        pipeline.process(obs)
        versions.append(outbox.pending()[-1].body["model_version"])
    assert versions == ["rf-test-2"] * 3
    assert outbox.pending()[-1].body["threshold"] == 0.5


@pytest.fixture
def backend_env(database_url, tmp_path) -> dict[str, str]:
    return {
        "VIGIL_DATABASE_URL": database_url,
        "VIGIL_SECRET_KEY": "model-update-secret",
        "VIGIL_FRONTEND_DIR": str(tmp_path / "no-frontend"),
    }


def _register(session_factory, robot_id: str, model_dir, stored_file) -> None:
    manifest, directory = read_manifest(model_dir)
    with transaction(session_factory) as session:
        model = ModelVersion(version=manifest.version, mode=manifest.mode, kind="rf",
                             file_path=str(stored_file), sha256=manifest.sha256,
                             manifest=manifest.model_dump(mode="json"))  # fmt: skip
        session.add(model)
        session.flush()
        session.get(Robot, robot_id).assigned_model_id = model.id


def _running_version(session_factory, robot_id: str) -> str | None:
    with session_factory() as session:
        return session.get(Robot, robot_id).running_model_version


@pytest.mark.timeout(90)
def test_assign_model_through_the_real_backend(
    backend_env, robot, session_factory, trained_model_dir, tmp_path
):
    v2 = derive_model(trained_model_dir, tmp_path / "v2", "rf-test-2")
    v3 = derive_model(trained_model_dir, tmp_path / "v3", "rf-test-3")
    # v2's file on the server was tampered with after registration
    stored_v2 = tmp_path / "server-v2.onnx"
    shutil.copy(v2 / "model.onnx", stored_v2)
    with open(stored_v2, "r+b") as handle:
        handle.seek(100)
        handle.write(b"tampered")
    _register(session_factory, robot, v2, stored_v2)
    backend = BackendProcess(backend_env, log_path=tmp_path / "backend.log").start()
    manager = ModelManager(tmp_path / "store", FrameClassifier.from_dir(trained_model_dir))
    outbox = Outbox(tmp_path / "o.sqlite")
    pipeline = FramePipeline(outbox, manager)
    client = RobotClient(backend.ws + "/ws/robot", robot, ROBOT_TOKEN, outbox, manager,
                         heartbeat_s=0.3, backoff=Backoff(base_s=0.1, cap_s=0.5))  # fmt: skip
    frames = _observations(generate_transport("walking", seed=5, duration_s=60))

    async def run_until(predicate, timeout_s: float = 20) -> None:
        deadline = time.monotonic() + timeout_s
        while not predicate():
            assert time.monotonic() < deadline, "timed out"
            pipeline.process(next(frames))
            client.notify()
            await asyncio.sleep(0.02)

    async def scenario() -> None:
        stop = asyncio.Event()
        task = asyncio.create_task(client.run(stop))
        pipeline.start_transport()
        await run_until(lambda: manager.last_refusal is not None)
        assert "sha256" in manager.last_refusal
        await run_until(lambda: _running_version(session_factory, robot) == "rf-test-1")
        assert manager.running_version == "rf-test-1"
        _register(session_factory, robot, v3, v3 / "model.onnx")  # an intact file
        await client._ws.close()  # reconnect: the backend re-sends the assignment
        await run_until(lambda: _running_version(session_factory, robot) == "rf-test-3")
        assert manager.running_version == "rf-test-3"
        stop.set()
        await task

    try:
        asyncio.run(scenario())
    finally:
        backend.stop()
        outbox.close()
    versions = {item.body.get("model_version") for item in Outbox(tmp_path / "o.sqlite").pending()}
    assert "rf-test-2" not in versions
