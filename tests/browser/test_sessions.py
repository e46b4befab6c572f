"""Sessions in Debian Chromium against the real backend: a session ended on the server (account
deactivated) closes the nurse's socket with 4401 and the page returns to sign-in instead of
reconnecting forever; the admin page manages users and robot tokens; no page breaks the
Content-Security-Policy."""

from __future__ import annotations

import httpx
import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.db import transaction
from backend.models import Robot, Role, User
from backend.security import robot_token_matches
from tests.support.passwords import password_hash

from .live_server import PASSWORD, ROBOT_ID, ROBOT_TOKEN, sign_in

pytestmark = pytest.mark.browser


def _watch_csp(page) -> list[str]:
    violations: list[str] = []
    page.on(
        "console",
        lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None,
    )
    return violations


def _add_admin(db) -> None:
    with transaction(db) as session:
        session.add(User(username="ada", password_hash=password_hash(PASSWORD), role=Role.ADMIN))


def test_a_deactivated_nurse_is_sent_back_to_sign_in(live_server, page, db):
    violations = _watch_csp(page)
    _add_admin(db)
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    # The socket's URL carries no token any more (uvicorn's access log records URLs).
    urls = page.evaluate("performance.getEntriesByType('resource').map(e => e.name)")
    assert not any("token=" in url for url in urls)

    admin = {"Authorization": f"Bearer {live_server.login('ada')}"}
    with db() as session:
        nina = session.scalars(select(User).where(User.username == "nina")).one()
    response = httpx.post(
        f"{live_server.base_url}/api/users/{nina.id}/deactivate", headers=admin, timeout=10
    )
    assert response.status_code == 200, response.text
    # The open socket is closed with 4401 at once: the page goes to sign-in (before the fix:
    # the socket was refused as 1006 and the board showed "reconnecting" forever).
    expect(page).to_have_url(f"{live_server.base_url}/login", timeout=5000)
    expect(page.get_by_role("button", name="Sign in")).to_be_visible()
    assert violations == []


def test_sign_out_revokes_the_session_on_the_server(live_server, page):
    sign_in(page, live_server.base_url)
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")
    token = page.evaluate("JSON.parse(sessionStorage.getItem('vigil.session')).token")
    page.get_by_role("button", name="Sign out").click()
    expect(page).to_have_url(f"{live_server.base_url}/login")
    me = f"{live_server.base_url}/api/auth/me"
    for _ in range(50):  # the logout request is sent as the page leaves
        status = httpx.get(me, headers={"Authorization": f"Bearer {token}"}).status_code
        if status == 401:
            break
        page.wait_for_timeout(100)
    assert status == 401


def test_admin_page_deactivates_users_and_rotates_robot_tokens(live_server, page, db):
    violations = _watch_csp(page)
    _add_admin(db)
    sign_in(page, live_server.base_url, username="ada")
    page.get_by_role("link", name="Users and robots").click()
    expect(page).to_have_url(f"{live_server.base_url}/admin")

    anna = page.locator("tr[data-user='anna']")
    anna.get_by_role("button", name="Deactivate").click()
    expect(anna).to_contain_text("deactivated")
    login = {"username": "anna", "password": PASSWORD}
    assert httpx.post(f"{live_server.base_url}/api/auth/login", json=login).status_code == 401
    anna.get_by_role("button", name="Reactivate").click()
    expect(anna).to_contain_text("active")

    form = page.get_by_role("form", name="New user")
    form.get_by_label("User name").fill("nate")
    form.get_by_label("Password").fill("a-long-password")
    form.get_by_label("Ward").fill("ward-a")
    form.get_by_role("button", name="Create user").click()
    expect(page.locator("tr[data-user='nate']")).to_contain_text("nurse")

    robot = page.locator(f"tr[data-robot='{ROBOT_ID}']")
    robot.get_by_role("button", name="Rotate token").click()
    token = page.get_by_label("new robot token").inner_text()
    with db() as session:
        stored = session.get(Robot, ROBOT_ID).token_hash
    assert robot_token_matches(stored, token) and not robot_token_matches(stored, ROBOT_TOKEN)
    robot.get_by_role("button", name="Revoke token").click()
    expect(robot).to_contain_text("revoked")
    with db() as session:
        assert session.get(Robot, ROBOT_ID).token_hash is None
    assert violations == []
