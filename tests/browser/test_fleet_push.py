"""The fleet page hears of a robot's switch at once (issue 35): after a promotion a connected
robot shows "switching…" until it reports the new model; the backend pushes that change on the
browser socket and the row says "in sync" without waiting for a poll. The page polls only as a
fallback (every 30 s), which this test never waits for. Debian Chromium against the real
backend, a worker and a simulated robot."""

from __future__ import annotations

import time

import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.models import ModelVersion, Robot
from tests.registry_fixtures import trained_model_dir  # noqa: F401
from vigil.protocol import Heartbeat

from .live_server import ROBOT_TOKEN, sign_in
from .simulated_robot import SimulatedRobot
from .test_engineer_console import system  # noqa: F401

pytestmark = pytest.mark.browser

#: Longer than the 3 s the page used to poll at, far shorter than its 30 s fallback poll.
QUIET_S = 4.5


def _inputs(factory) -> list[str] | None:
    with factory() as session:
        return session.get(Robot, "robot-a").inputs


def test_the_fleet_row_follows_the_robot_s_switch_without_a_poll(system, page):  # noqa: F811
    server, factory = system
    with factory() as session:
        sha256 = session.scalars(
            select(ModelVersion.sha256).where(ModelVersion.version == "rf-test-1")
        ).one()
    fleet_reads: list[float] = []
    page.on(
        "request",
        lambda request: "/api/fleet" in request.url and fleet_reads.append(time.monotonic()),
    )
    sign_in(page, server.base_url, "erin")
    # The test models need floor measures: the robot's hello says it feeds them.
    feeds = ["keypoints", "depth", "floor"]
    with SimulatedRobot(server.robot_ws_url, "robot-a", ROBOT_TOKEN, inputs=feeds) as robot:
        deadline = time.monotonic() + 10  # the writer stores the hello just after the welcome
        while _inputs(factory) != feeds:
            assert time.monotonic() < deadline, "the robot's hello was never stored"
            time.sleep(0.05)
        page.get_by_role("link", name="rf-test-1").click()
        page.get_by_label("Robot", exact=True).select_option("robot-a")
        page.get_by_role("button", name="Sign off and promote").click()
        page.get_by_role("dialog", name="Confirm promotion").get_by_role(
            "button", name="Confirm promotion"
        ).click()
        expect(page.get_by_role("status")).to_contain_text("active")

        page.get_by_role("link", name="Fleet & deployments").click()
        row = page.get_by_role("table", name="Fleet").locator("tr[data-robot='robot-a']")
        expect(row).to_contain_text("rf-test-1")  # the target
        expect(row).to_contain_text("sim-1")  # still running the old one
        expect(row).to_contain_text("switching…")

        # The page sits quiet: no poll every few seconds. (Waited through Playwright, which
        # delivers the page's request events meanwhile; a plain sleep would hold them back.)
        quiet_from = time.monotonic()
        page.wait_for_timeout(QUIET_S * 1000)
        polled = [at for at in fleet_reads if at > quiet_from]
        assert polled == [], f"the fleet page read /api/fleet {len(polled)} times while quiet"
        expect(row).to_contain_text("switching…")

        # The robot loaded the model and says so: the row follows at once (pushed).
        reported = time.monotonic()
        robot.send(Heartbeat(ts=time.time(), running_model="rf-test-1", running_sha256=sha256))
        expect(row).to_contain_text("in sync", timeout=5_000)
        assert time.monotonic() - reported < 10  # far within the 30 s fallback poll
        expect(row).not_to_contain_text("switching…")
        expect(row.locator("td").nth(6)).to_have_text("rf-test-1")  # running version
