"""The engineer console in Debian Chromium against the real backend and a worker: registry with
gold-set metrics and plots, the gate blocking a model that misses a fall, promotion, the fleet
view, a what-if replay job with live progress, and a one-click rollback."""

from __future__ import annotations

import threading

import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.db import make_engine, make_session_factory, transaction
from backend.jobs import queue
from backend.labelling.importers.urfd import import_urfd
from backend.models import Deployment, Robot, Role, User
from backend.models.jobs import JobKind
from backend.models.videos import Split
from tests.registry_fixtures import GOLD, TRAIN, derive_model, trained_model_dir  # noqa: F401
from tests.support.passwords import password_hash
from worker.runner import Worker
from worker.settings import WorkerSettings

from .live_server import PASSWORD, SCREENSHOTS, LiveServer, sign_in

pytestmark = pytest.mark.browser


@pytest.fixture
def system(tmp_path, frontend_dist, trained_model_dir):  # noqa: F811
    server = LiveServer.create(tmp_path, frontend_dist)
    store = tmp_path / "models"
    server.env |= {"VIGIL_MODEL_STORE_DIR": str(store), "VIGIL_GATE_FALSE_ALARM_BUDGET": "0.5"}
    engine = make_engine(server.database_url)
    factory = make_session_factory(engine)
    with transaction(factory) as session:
        session.add(
            User(username="erin", password_hash=password_hash(PASSWORD), role=Role.ENGINEER)
        )
        import_urfd(session, names=TRAIN[:2] + TRAIN[6:8], split=Split.TRAIN)
        import_urfd(session, names=GOLD, split=Split.TEST)
        queue.enqueue(session, JobKind.REGISTER, {"path": str(trained_model_dir)})
        blind = derive_model(trained_model_dir, tmp_path / "blind", "blind-1", delay_ms=10_000)
        queue.enqueue(session, JobKind.REGISTER, {"path": str(blind)})
        overlap = derive_model(
            trained_model_dir,
            tmp_path / "overlap",
            "overlap-1",
            training_recordings=[*TRAIN, "fall-08"],
        )
        queue.enqueue(session, JobKind.REGISTER, {"path": str(overlap)})
    settings = WorkerSettings(
        database_url=server.database_url,
        model_store_dir=store,
        worker_id="browser-worker",
        worker_poll_s=0.2,
        worker_heartbeat_s=0.3,
        worker_sweep_s=5,
    )
    worker = Worker(settings, factory)
    assert all(worker.run_once() for _ in range(3))  # registered before the page opens
    thread = threading.Thread(target=worker.run_forever, daemon=True)
    thread.start()
    server.start()
    yield server, factory
    server.stop()
    worker.stop()
    thread.join(10)
    engine.dispose()


def test_engineer_registry_gate_promote_what_if_and_rollback(system, page):
    server, factory = system
    sign_in(page, server.base_url, "erin")
    expect(page).to_have_url(f"{server.base_url}/engineer")
    models = page.get_by_role("table", name="Models")
    expect(models).to_contain_text("rf-test-1")
    expect(models).to_contain_text("blind-1")

    # The blind model (10 s delay) misses both gold falls: the gate blocks it.
    page.get_by_role("link", name="blind-1").click()
    gate = page.get_by_label("Gate")
    expect(gate).to_contain_text("blocked")
    expect(gate).to_contain_text("0 of 2 falls detected")
    expect(page.get_by_role("button", name="Sign off and promote")).to_be_disabled()

    # Trained on a gold recording: its gold-set figures are training figures, and the page
    # names the recording.
    page.get_by_role("link", name="Model registry").click()
    page.get_by_role("link", name="overlap-1").click()
    expect(page.get_by_label("Gold set and training")).to_have_text(
        "Judged on 4 gold recordings, 1 of which it was trained on (fall-08): training figures, "
        "so the gate refuses it."
    )
    expect(page.get_by_label("Gate")).to_contain_text(
        "1 of 4 gold recordings were also training data: fall-08"
    )

    page.get_by_role("link", name="Model registry").click()
    page.get_by_role("link", name="rf-test-1").click()
    expect(page.get_by_role("table", name="Table 3")).to_be_visible()
    expect(page.get_by_label("Gold set and training")).to_have_text(
        "Judged on 4 gold recordings it was not trained on (trained on 12 other recordings)."
    )
    expect(page.get_by_role("img", name="plot roc_pr")).to_be_visible()
    expect(page.get_by_label("Gate")).to_contain_text("passed")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SCREENSHOTS / "engineer-model.png", full_page=True)

    # What-if with a 10 s delay, run by the worker, progress shown live, then the change.
    page.get_by_label("Delay (ms)").fill("10000")
    page.get_by_role("button", name="Replay labelled recordings").click()
    result = page.get_by_role("table", name="What-if result")
    expect(result).to_be_visible(timeout=30_000)
    expect(result.locator("tr[data-metric=falls_detected]")).to_contain_text("-2")
    expect(result.locator("tr[data-metric=falls_detected]")).to_contain_text("Falls detected")

    expect(page.get_by_label("Scope")).to_have_value("robot")  # the narrowest scope by default
    expect(page.get_by_role("button", name="Sign off and promote")).to_be_disabled()  # no robot yet
    page.get_by_label("Robot", exact=True).select_option("robot-a")
    qualifying = page.get_by_role("table", name="Qualifying robots")
    expect(qualifying.get_by_role("row", name="robot-a")).to_contain_text("no: lacks floor")
    expect(page.get_by_text("The model needs keypoints, floor in every frame")).to_be_visible()
    # robot-a never said what it feeds (keypoints only): the floor model is refused.
    page.get_by_role("button", name="Sign off and promote").click()
    confirm = page.get_by_role("dialog", name="Confirm promotion")
    expect(confirm).to_contain_text("Promote rf-test-1 to robot robot-a: 1 robot (robot-a)")
    confirm.get_by_role("button", name="Confirm promotion").click()
    expect(page.get_by_role("alert")).to_have_text(
        "robot robot-a cannot feed model rf-test-1: it has no floor measures"
    )
    with transaction(factory) as session:  # its hello said it has a calibrated depth camera
        session.get(Robot, "robot-a").inputs = ["keypoints", "depth", "floor"]
    page.get_by_role("button", name="Sign off and promote").click()
    page.get_by_role("button", name="Back").click()  # changing one's mind promotes nothing
    expect(confirm).to_have_count(0)
    with factory() as session:
        assert session.get(Robot, "robot-a").assigned_model_id is None
    page.get_by_role("button", name="Sign off and promote").click()
    confirm.get_by_role("button", name="Confirm promotion").click()
    expect(page.get_by_role("status")).to_contain_text("active")
    # The status says where the model runs (this fleet has one robot) rather than a bare word.
    expect(page.locator("h1 .pill")).to_have_text("production on every robot")
    expect(qualifying.get_by_role("row", name="robot-a")).to_contain_text("yes")
    with factory() as session:
        assert session.get(Robot, "robot-a").assigned_model_id is not None

    page.get_by_role("link", name="Fleet & deployments").click()
    fleet = page.get_by_role("table", name="Fleet")
    expect(fleet.get_by_role("row", name="robot-a")).to_contain_text("rf-test-1")
    expect(fleet.get_by_role("row", name="robot-a")).to_contain_text("pending: robot offline")
    expect(fleet.get_by_role("row", name="robot-a")).to_contain_text("keypoints, depth, floor")
    page.screenshot(path=SCREENSHOTS / "engineer-fleet.png", full_page=True)
    page.get_by_role("table", name="Deployments").get_by_role("button", name="Roll back").click()
    confirm_rollback = page.get_by_role("dialog", name="Confirm rollback")
    confirm_rollback.get_by_label("Reason").fill("checking the rollback")
    confirm_rollback.get_by_role("button", name="Confirm rollback").click()
    expect(page.get_by_role("table", name="Deployments")).to_contain_text("rolled_back")
    with factory() as session:
        assert session.get(Robot, "robot-a").assigned_model_id is None
        (deployment,) = session.scalars(select(Deployment)).all()
        assert deployment.status == "rolled_back" and deployment.gate_report["passed"]

    page.get_by_role("link", name="Jobs").click()
    jobs = page.get_by_role("table", name="Jobs")
    expect(jobs).to_contain_text("whatif")
    jobs.get_by_role("row").filter(has_text="whatif").get_by_role("button", name="Log").click()
    expect(page.locator("pre.job-log")).to_contain_text("replaying 4 recordings")

    page.get_by_role("link", name="Model registry").click()
    page.get_by_label("pick rf-test-1").check()
    page.get_by_label("pick blind-1").check()
    page.get_by_role("button", name="Compare the two selected").click()
    comparison = page.get_by_role("table", name="Comparison")
    expect(comparison.get_by_role("row", name="Delay (ms)")).to_contain_text("10000")
    expect(comparison.get_by_role("row", name="Falls detected")).to_contain_text("-2")
    expect(comparison).not_to_contain_text("fp_d")
    page.screenshot(path=SCREENSHOTS / "engineer-compare.png", full_page=True)
