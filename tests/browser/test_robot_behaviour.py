"""What the robot did (issue 33): the robot reports its behaviour (behaviour_changed); the
nurse's alarm card and replay page say it in a nurse's words, the fleet page shows each robot's
state. Debian Chromium against the real backend and a simulated robot."""

from __future__ import annotations

import time

import pytest
from playwright.sync_api import expect

from backend.db import transaction
from backend.models import Role, User
from tests.support.passwords import password_hash
from vigil.protocol import BehaviourChanged

from .live_server import PASSWORD, ROBOT_TOKEN, sign_in
from .simulated_robot import SimulatedRobot, fall_frames

pytestmark = pytest.mark.browser


def test_the_board_and_the_fleet_show_what_the_robot_did(live_server, page, db, chromium):
    with transaction(db) as session:
        session.add(
            User(username="erin", password_hash=password_hash(PASSWORD), role=Role.ENGINEER)
        )
    sign_in(page, live_server.base_url)
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-1", patient="P-17", location="corridor B")
        frames = fall_frames(0, time.time() - 5, "t-1")
        robot.stream(frames)
        card = page.locator("article.alarm")
        expect(card).to_have_count(1)
        expect(card.get_by_test_id("robot-state")).to_have_count(0)  # the robot has not said
        stopped = time.time()
        robot.send(
            BehaviourChanged(
                ts=stopped,
                since=stopped,
                state="emergency_stop",
                transport_id="t-1",
                reason="Emergency decision: stop, call for help",
            )
        )
        robot.send_batch(frames[-1:])
        robot.wait_ack(frames[-1].seq)
        expect(card.get_by_test_id("robot-state")).to_contain_text(
            "Robot stopped, waiting for help since"
        )
        alarm_id = card.get_attribute("data-alarm-id")

        # The replay page says it too; the fleet page shows the robot's state.
        page.goto(f"{live_server.base_url}/nurse/alarms/{alarm_id}")
        expect(page.locator("main.replay").get_by_test_id("robot-state")).to_contain_text(
            "Robot stopped, waiting for help"
        )
        engineer = chromium.new_page()
        try:
            sign_in(engineer, live_server.base_url, "erin")
            engineer.get_by_role("link", name="Fleet & deployments").click()
            row = engineer.get_by_role("table", name="Fleet").locator("tr[data-robot='robot-a']")
            expect(row.get_by_test_id("behaviour")).to_contain_text("emergency stop since")
            expect(row.get_by_test_id("behaviour")).to_have_attribute(
                "title", "Emergency decision: stop, call for help"
            )
            # Released: the fleet follows on its next poll.
            released = time.time()
            robot.send(
                BehaviourChanged(
                    ts=released,
                    since=released,
                    state="transporting",
                    transport_id="t-1",
                    reason="reset on the robot",
                )
            )
            robot.send_batch(frames[-1:])
            robot.wait_ack(frames[-1].seq)
            expect(row.get_by_test_id("behaviour")).to_contain_text("transporting since")
        finally:
            engineer.close()
    page.goto(f"{live_server.base_url}/nurse")
    expect(page.locator("article.alarm").get_by_test_id("robot-state")).to_contain_text(
        "Robot driving since"
    )
