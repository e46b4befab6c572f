"""Model updates against the real backend: an assigned model is downloaded with the robot's
token, verified, swapped in between two frames and reported; a tampered file is refused and the
old model keeps running."""

from __future__ import annotations

import time
from pathlib import Path

from backend.db import make_engine, make_session_factory, transaction
from backend.models import Robot
from backend.models.registry import ModelVersion
from tests.support.live_backend import ROBOT_ID
from vigil.model_file import read_manifest

from .conftest import query, wait_for
from .tiny_model import write_upright_model

ENDLESS_GENERATED = [
    "--source",
    "generated",
    "--loop",
    "--seed",
    "5",
    "--people",
    "1",
    "--duration-s",
    "20",
]


def assign(backend, model_dir: Path, tamper: bool = False, shadow: bool = False) -> str:
    """Register a model directory as the registry would, optionally damage the file on disk
    afterwards, and assign it to robot-a; returns the version."""
    manifest, directory = read_manifest(model_dir)
    if tamper:
        path = directory / manifest.file
        path.write_bytes(path.read_bytes() + b"\x00")
    engine = make_engine(backend.database_url)
    with transaction(make_session_factory(engine)) as session:
        model = ModelVersion(
            version=manifest.version,
            mode=manifest.mode,
            kind="test",
            file_path=str(directory / manifest.file),
            sha256=manifest.sha256,
            manifest=manifest.model_dump(mode="json"),
        )
        session.add(model)
        session.flush()
        robot = session.get(Robot, ROBOT_ID)
        if shadow:
            robot.shadow_model_id = model.id
        else:
            robot.assigned_model_id = model.id
    engine.dispose()
    return manifest.version


def running_version(backend) -> str | None:
    return query(backend, "SELECT running_model_version FROM robots WHERE id = ?", ROBOT_ID)[0][0]


def versions_in_seq_order(backend) -> list[str]:
    rows = query(
        backend, "SELECT model_version FROM frames WHERE robot_id = ? ORDER BY seq", ROBOT_ID
    )
    return [version for (version,) in rows]


def test_assigned_model_is_swapped_in_and_its_version_reported(backend, agents, tmp_path):
    v1 = write_upright_model(tmp_path / "v1", "upright-1")
    agent = agents(backend, *ENDLESS_GENERATED, "--model-dir", str(v1))
    wait_for(lambda: running_version(backend) == "upright-1", 30, "hello with upright-1")
    wait_for(lambda: len(versions_in_seq_order(backend)) > 20, 30, "frames from upright-1")

    assign(backend, write_upright_model(tmp_path / "store" / "v2", "upright-2", delay_ms=0))
    wait_for(lambda: running_version(backend) == "upright-2", 30, "heartbeat with upright-2")
    wait_for(lambda: versions_in_seq_order(backend)[-1] == "upright-2", 30, "upright-2 frames")
    versions = versions_in_seq_order(backend)
    switch = versions.index("upright-2")
    assert set(versions[:switch]) == {"upright-1"} and set(versions[switch:]) == {"upright-2"}
    ((count, last),) = query(
        backend, "SELECT COUNT(*), MAX(seq) FROM frames WHERE robot_id = ?", ROBOT_ID
    )
    assert count == last + 1  # no frame lost around the swap
    assert (tmp_path / "robot-models" / ROBOT_ID / "upright-2" / "model.onnx").is_file()
    assert "model upright-2 now classifies the frames" in agent.log()


def test_tampered_model_is_refused_and_the_old_model_keeps_running(backend, agents, tmp_path):
    v1 = write_upright_model(tmp_path / "v1", "upright-1")
    agent = agents(backend, *ENDLESS_GENERATED, "--model-dir", str(v1))
    wait_for(lambda: running_version(backend) == "upright-1", 30, "hello with upright-1")

    assign(backend, write_upright_model(tmp_path / "store" / "v2", "upright-2"), tamper=True)
    wait_for(lambda: "model upright-2 refused: sha256" in agent.log(), 30, "the refusal")
    wait_for(
        lambda: "refused a model: model upright-2 refused" in backend.log_path.read_text(),
        15,
        "the refusal reported to the backend",
    )
    stored = len(versions_in_seq_order(backend))
    time.sleep(2)
    versions = versions_in_seq_order(backend)
    assert len(versions) > stored  # still streaming
    assert set(versions) == {"upright-1"}
    assert running_version(backend) == "upright-1"
    assert not (tmp_path / "robot-models" / ROBOT_ID / "upright-2").exists()
    assert agent.process.poll() is None


def test_shadow_model_decides_beside_the_assigned_one_without_alarming(backend, agents, tmp_path):
    # Assigned before the robot connects: the backend sends it right after welcome.
    assign(
        backend,
        write_upright_model(tmp_path / "store" / "c1", "candidate-1", threshold=0.9),
        shadow=True,
    )
    v1 = write_upright_model(tmp_path / "v1", "upright-1")
    agent = agents(backend, *ENDLESS_GENERATED, "--model-dir", str(v1))

    def shadow_frames():
        return query(
            backend,
            "SELECT model_version, shadow_model_version FROM frames "
            "WHERE robot_id = ? AND shadow_model_version IS NOT NULL",
            ROBOT_ID,
        )

    rows = wait_for(shadow_frames, 30, "frames with shadow decisions")
    assert set(rows) == {("upright-1", "candidate-1")}
    assert running_version(backend) == "upright-1"
    assert "shadow model candidate-1 runs beside upright-1" in agent.log()
