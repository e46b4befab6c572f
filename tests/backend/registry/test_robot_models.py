"""Models reach robots: a separate robot process switches to the promoted version and reports
it, a rollback brings the old one back; shadow decisions are stored but never alarm, and their
disagreements land in the review queue."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest
import uvicorn
from sqlalchemy import func, select
from websockets.sync.client import connect

from backend.db import transaction
from backend.main import create_app
from backend.models import (
    Alarm,
    AnnotationSegment,
    Frame,
    Robot,
    Role,
    SegmentSource,
    SegmentStatus,
)
from backend.registry.sweeps import shadow_disagreements
from tests.backend.conftest import ROBOT_TOKEN
from tests.registry_fixtures import derive_model, second_version
from vigil.protocol import FrameBatch, FrameRecord, Hello, ShadowDecision, TransportStart

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture
def live_server(settings):
    """The real backend on a free port (uvicorn in a thread)."""
    app = create_app(settings)
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started:
        assert time.monotonic() < deadline, "backend did not start"
        time.sleep(0.05)
    port = server.servers[0].sockets[0].getsockname()[1]
    yield f"127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10)


def _wait_running(session_factory, robot_id: str, version: str, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with session_factory() as session:
            if session.get(Robot, robot_id).running_model_version == version:
                return
        time.sleep(0.1)
    raise AssertionError(f"{robot_id} did not report running {version}")


def _wait_frames(session_factory, robot_id: str, version: str, timeout: float = 30) -> None:
    """Frames of `robot_id` classified by `version` are stored."""
    query = select(func.count()).where(Frame.robot_id == robot_id, Frame.model_version == version)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with session_factory() as session:
            if session.scalar(query):
                return
        time.sleep(0.1)
    raise AssertionError(f"no frames of {robot_id} classified by {version} were stored")


def test_robot_agent_process_switches_to_the_promoted_version_and_back_on_rollback(
    live_server,
    make_account,
    fleet,
    urfd_db,
    register,
    keypoints_model_dir,
    tmp_path,
    session_factory,
):
    """The real `vigil-robot simulate` agent (GENERATED transports, classified on the robot by
    the model it runs) against the real backend. Keypoints-only models: the robot may feed them
    whatever inputs its hello names."""
    engineer = make_account(Role.ENGINEER)
    v1 = register(keypoints_model_dir)
    v2 = register(
        derive_model(
            keypoints_model_dir, tmp_path / "v2", "rf-kp-test-2", threshold=0.5, delay_ms=400
        )
    )
    api = httpx.Client(base_url=f"http://{live_server}", headers=engineer.headers, timeout=10)
    first = api.post(f"/api/models/{v1}/promote", json={"scope": "robot", "target": "robot-a"})
    assert first.status_code == 201, first.text
    tokens = tmp_path / "tokens.json"
    tokens.write_text(json.dumps({"robot-a": ROBOT_TOKEN}))
    models = tmp_path / "robot-models"  # the robot's store of assigned models: <robot>/<version>
    agent = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "robot_agent.cli",
            "simulate",
            "--backend",
            f"ws://{live_server}/ws/robot",
            "--robots",
            "1",
            "--tokens-file",
            str(tokens),
            "--model-dir",
            str(keypoints_model_dir),
            "--models-dir",
            str(models),
            "--outbox-dir",
            str(tmp_path / "outbox"),
            "--transports",
            "1",
            "--duration-s",
            "600",
        ],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_running(session_factory, "robot-a", "rf-kp-test-1")  # it starts with v1
        _wait_frames(session_factory, "robot-a", "rf-kp-test-1")  # and classifies frames with it
        # Promoted while connected: pushed at once, downloaded with the robot token, verified.
        second = api.post(
            f"/api/models/{v2}/promote", json={"scope": "robot", "target": "robot-a"}
        ).json()
        _wait_running(session_factory, "robot-a", "rf-kp-test-2")
        assert (models / "robot-a" / "rf-kp-test-2" / "model.onnx").is_file()
        row = {r["id"]: r for r in api.get("/api/fleet").json()}["robot-a"]
        assert (
            row["connected"],
            row["target_version"],
            row["running_version"],
            row["in_sync"],
        ) == (True, "rf-kp-test-2", "rf-kp-test-2", True)
        # One click back.
        assert api.post(f"/api/deployments/{second['id']}/rollback", json={}).status_code == 200
        _wait_running(session_factory, "robot-a", "rf-kp-test-1")
        # A change made outside this backend (the worker's automatic rollback writes only the
        # database) reaches the robot through the backend's reconcile loop.
        with transaction(session_factory) as session:
            session.get(Robot, "robot-a").assigned_model_id = v2
        _wait_running(session_factory, "robot-a", "rf-kp-test-2")
        _wait_frames(session_factory, "robot-a", "rf-kp-test-2")  # it classifies with it
        with session_factory() as session:  # it streamed frames classified by its models only
            versions = set(
                session.scalars(
                    select(Frame.model_version).where(Frame.robot_id == "robot-a").distinct()
                )
            )
        assert versions == {"rf-kp-test-1", "rf-kp-test-2"}
    finally:
        agent.terminate()
        _, err = agent.communicate(timeout=20)
    # main's agent logs "model X refused: ...; model Y keeps running" for a model it rejects
    assert " refused" not in err and "keeps running" not in err, err


def _frame(seq: int, decision: str, shadow: str) -> FrameRecord:
    return FrameRecord(
        seq=seq,
        ts=1000.0 + seq / 30,
        transport_id="t-1",
        keypoints=[[100.0 + i, 200.0 + i, 0.9] for i in range(25)],
        decision=decision,
        scores={decision: 0.9},
        model_version="prod-1",
        shadow=ShadowDecision(decision=shadow, scores={shadow: 0.95}, model_version="cand-1"),
    )


def test_shadow_decisions_never_alarm_and_disagreements_go_to_review(
    client, robot, session_factory, factory, worker_settings
):
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id=robot, token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text())["type"] == "welcome"
        ws.send_text(
            TransportStart(transport_id="t-1", mode="walking", ts=1000.0).model_dump_json()
        )
        frames = [_frame(i, "normal", "emergency" if 3 <= i <= 8 else "normal") for i in range(12)]
        ws.send_text(FrameBatch(frames=frames).model_dump_json())
        assert json.loads(ws.receive_text()) == {"type": "ack", "seq": 11}
    with session_factory() as session:
        assert session.scalar(select(func.count()).select_from(Alarm)) == 0
        stored = session.scalars(select(Frame).order_by(Frame.seq)).all()
        assert [f.shadow_decision for f in stored[2:5]] == ["normal", "emergency", "emergency"]
        assert {f.shadow_model_version for f in stored} == {"cand-1"}
    shadow_disagreements(factory, worker_settings)
    shadow_disagreements(factory, worker_settings)  # idempotent
    with session_factory() as session:
        (segment,) = session.scalars(select(AnnotationSegment)).all()
        assert (segment.first_frame, segment.last_frame) == (3, 8)
        assert segment.source == SegmentSource.SHADOW_DISAGREEMENT
        assert segment.status == SegmentStatus.PENDING and segment.priority == 2
        assert "shadow cand-1 said emergency" in segment.review_comment


def test_a_shadow_assignment_reaches_the_robot_on_connect(
    client, make_account, fleet, urfd_db, register, trained_model_dir, session_factory
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    response = client.post(
        f"/api/models/{v1}/shadow",
        headers=engineer.headers,
        json={"scope": "robot", "target": "robot-b"},
    )
    assert response.status_code == 201 and response.json()["shadow"] is True
    with session_factory() as session:
        robot = session.get(Robot, "robot-b")
        assert robot.shadow_model_id == v1 and robot.assigned_model_id is None
    with client.websocket_connect("/ws/robot") as ws:
        ws.send_text(Hello(robot_id="robot-b", token=ROBOT_TOKEN).model_dump_json())
        assert json.loads(ws.receive_text())["type"] == "welcome"
        assignment = json.loads(ws.receive_text())
    assert assignment["type"] == "assign_model" and assignment["shadow"] is True
    assert assignment["version"] == "rf-test-1"
    assert assignment["url"].endswith("/api/robot/models/rf-test-1/file")


def test_withdrawing_a_shadow_deployment_tells_the_connected_robot_to_stop_it(
    live_server, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path
):
    engineer = make_account(Role.ENGINEER)
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.5))
    api = httpx.Client(base_url=f"http://{live_server}", headers=engineer.headers, timeout=10)
    target = {"scope": "robot", "target": "robot-b"}
    assert api.post(f"/api/models/{v1}/promote", json=target).status_code == 201
    shadow = api.post(f"/api/models/{v2}/shadow", json=target).json()
    with connect(f"ws://{live_server}/ws/robot") as ws:
        hello = Hello(robot_id="robot-b", token=ROBOT_TOKEN, running_model="rf-test-1")
        ws.send(hello.model_dump_json())
        assert json.loads(ws.recv(timeout=10))["type"] == "welcome"
        production, candidate = (json.loads(ws.recv(timeout=10)) for _ in range(2))
        assert (production["version"], production["shadow"]) == ("rf-test-1", False)
        assert "stop_shadow" not in production  # only sent when true: older agents read it
        assert (candidate["version"], candidate["shadow"]) == ("rf-test-2", True)
        assert api.post(f"/api/deployments/{shadow['id']}/rollback", json={}).status_code == 200
        stop = json.loads(ws.recv(timeout=10))
    assert (stop["type"], stop["version"], stop["shadow"], stop["stop_shadow"]) == (
        "assign_model",
        "rf-test-1",
        False,
        True,
    )


def test_robot_agent_runs_a_shadow_model_that_never_alarms(
    live_server,
    make_account,
    fleet,
    urfd_db,
    register,
    trained_model_dir,
    tmp_path,
    session_factory,
    factory,
    worker_settings,
):
    """Production: a model that cannot alarm within the short transport (10 s delay). Shadow: the
    same graph at threshold 0, which calls every frame Emergency. Only the shadow disagrees."""
    engineer = make_account(Role.ENGINEER)
    quiet = derive_model(trained_model_dir, tmp_path / "quiet", "quiet-1", delay_ms=10_000)
    eager = derive_model(
        trained_model_dir, tmp_path / "eager", "eager-1", threshold=0.0, delay_ms=0
    )
    production, candidate = register(quiet), register(eager)
    with transaction(session_factory) as session:  # what the robot already runs
        session.get(Robot, "robot-a").assigned_model_id = production
    api = httpx.Client(base_url=f"http://{live_server}", headers=engineer.headers, timeout=10)
    shadow = api.post(
        f"/api/models/{candidate}/shadow", json={"scope": "robot", "target": "robot-a"}
    )
    assert shadow.status_code == 201, shadow.text
    tokens = tmp_path / "tokens.json"
    tokens.write_text(json.dumps({"robot-a": ROBOT_TOKEN}))
    agent = subprocess.run(
        [
            sys.executable,
            "-m",
            "robot_agent.cli",
            "simulate",
            "--backend",
            f"ws://{live_server}/ws/robot",
            "--robots",
            "1",
            "--tokens-file",
            str(tokens),
            "--model-dir",
            str(quiet),
            "--models-dir",
            str(tmp_path / "models"),
            "--outbox-dir",
            str(tmp_path / "outbox"),
            "--transports",
            "1",
            "--duration-s",
            "6",
            "--speed",
            "2",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert agent.returncode == 0, agent.stderr
    with session_factory() as session:
        frames = session.scalars(
            select(Frame).where(Frame.robot_id == "robot-a").order_by(Frame.seq)
        ).all()
        shadowed = [f for f in frames if f.shadow_model_version == "eager-1"]
        assert len(shadowed) > 30, agent.stderr
        assert {f.shadow_decision for f in shadowed} == {"emergency"}
        assert {f.model_version for f in frames} == {"quiet-1"}
        assert "emergency" not in {f.decision for f in frames}
        assert session.scalar(select(func.count()).select_from(Alarm)) == 0
    shadow_disagreements(factory, worker_settings)
    with session_factory() as session:
        segments = session.scalars(
            select(AnnotationSegment).where(
                AnnotationSegment.source == SegmentSource.SHADOW_DISAGREEMENT
            )
        ).all()
        assert segments
        assert {(s.status, s.model_version, s.label_key) for s in segments} == {
            (SegmentStatus.PENDING, "eager-1", "falling")
        }
