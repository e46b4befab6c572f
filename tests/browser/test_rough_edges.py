"""Rough edges people tripped on (issue 35), in Debian Chromium against the real backend."""

from __future__ import annotations

from datetime import timedelta

import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.alarms import service
from backend.alarms.service import DecisionEvidence
from backend.db import transaction
from backend.models import AlarmKind, Robot, User

from .live_server import sign_in

pytestmark = pytest.mark.browser


def test_unknown_and_forbidden_pages_say_so_with_a_way_back(live_server, page):
    sign_in(page, live_server.base_url)  # nina, a nurse
    expect(page.locator("main.board")).to_be_visible()

    # A page the nurse may not open: told so, not silently sent to the board.
    page.goto(f"{live_server.base_url}/engineer/fleet")
    expect(page.get_by_role("heading", name="Not allowed here")).to_be_visible()
    expect(page).to_have_url(f"{live_server.base_url}/engineer/fleet")
    page.get_by_role("link", name="Back to your start page").click()
    expect(page).to_have_url(f"{live_server.base_url}/nurse")
    expect(page.locator("main.board")).to_be_visible()

    # An address that is no page at all.
    page.goto(f"{live_server.base_url}/nurse/no-such-page")
    expect(page.get_by_role("heading", name="Page not found")).to_be_visible()
    expect(page.get_by_text("There is no page at /nurse/no-such-page.")).to_be_visible()
    page.get_by_role("link", name="Back to your start page").click()
    expect(page).to_have_url(f"{live_server.base_url}/nurse")


def test_history_says_the_time_to_acknowledge_in_minutes_and_hours(live_server, page, db):
    """Not "2972 s": the history's Ack column in minutes and hours, as the fatigue page."""
    with transaction(db) as session:
        robot = session.get(Robot, "robot-a")
        nurse = session.scalars(select(User).where(User.username == "nina")).one()
        evidence = DecisionEvidence(seq=None, ts=None)
        waited = {}
        for kind, seconds in ((AlarmKind.EMERGENCY, 2972), (AlarmKind.PAUSE, 245)):
            alarm, _ = service.raise_or_update(session, robot, None, kind, evidence)
            service.acknowledge(session, alarm, nurse)
            # Raised that long before the acknowledgement (a recorded shift, back-dated).
            alarm.raised_at = alarm.acknowledged_at - timedelta(seconds=seconds)
            session.flush()
            waited[alarm.id] = seconds
        unacknowledged, _ = service.raise_or_update(
            session, robot, None, AlarmKind.ROBOT_OFFLINE, evidence
        )
        waited[unacknowledged.id] = None
    sign_in(page, live_server.base_url)
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")
    page.goto(f"{live_server.base_url}/nurse/history")
    table = page.get_by_role("table", name="Alarms")
    expect(table.locator("tbody tr")).to_have_count(3)
    shown = {
        alarm_id: table.locator("tbody tr").filter(
            has=page.get_by_role("link", name=str(alarm_id), exact=True)
        )
        for alarm_id in waited
    }
    expected = {2972: "50 min", 245: "4 min 05 s", None: "–"}
    for alarm_id, seconds in waited.items():
        expect(shown[alarm_id].get_by_test_id("time-to-ack")).to_have_text(expected[seconds])
    expect(table).not_to_contain_text("2972 s")
