"""Rough edges people tripped on (issue 35), in Debian Chromium against the real backend."""

from __future__ import annotations

import pytest
from playwright.sync_api import expect

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
