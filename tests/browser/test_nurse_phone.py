"""The nurse's board on a phone (issue 32): a 390x844 viewport (Chromium device emulation),
the newest alarm and its Acknowledge button visible without scrolling, installable as a web
app (manifest, icons, service worker), and a system notification when an alarm arrives while
the page is in the background."""

from __future__ import annotations

import json
import time

import httpx
import pytest
from playwright.sync_api import expect

from .live_server import ROBOT_TOKEN, SCREENSHOTS, sign_in
from .simulated_robot import SimulatedRobot, fall_frames

pytestmark = pytest.mark.browser

PHONE = {"width": 390, "height": 844}

# Records what the page asks the system to show, and lets the test put the page in the
# background (document.visibilityState "hidden", as when the phone is in a pocket).
RECORD_NOTIFICATIONS = """
window.__notices = [];
window.__hidden = false;
Object.defineProperty(document, "visibilityState",
                      { get: () => window.__hidden ? "hidden" : "visible" });
Object.defineProperty(document, "hidden", { get: () => window.__hidden });
const original = ServiceWorkerRegistration.prototype.showNotification;
ServiceWorkerRegistration.prototype.showNotification = function (title, options) {
  window.__notices.push({ title, body: options.body, tag: options.tag, via: "service worker",
                          requireInteraction: !!options.requireInteraction });
  return original.call(this, title, options);
};
"""


def _wait(condition, what: str, timeout: float = 10.0) -> None:
    # (the page's CSP forbids the string evaluation wait_for_function uses)
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


@pytest.fixture
def phone(chromium):
    context = chromium.new_context(
        viewport=PHONE,
        device_scale_factor=3,
        is_mobile=True,
        has_touch=True,
        permissions=["notifications"],
    )
    context.add_init_script(RECORD_NOTIFICATIONS)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    yield page
    context.close()
    assert errors == []


def test_the_board_on_a_phone_installable_and_notifying_in_the_background(live_server, phone):
    page = phone
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    page.get_by_role("button", name="Start shift").click()
    # The service worker is ready (installable, and notifications come from it).
    assert page.evaluate("() => navigator.serviceWorker.ready.then((r) => !!r.active)")

    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-1", patient="P-17", location="corridor B")
        robot.stream(fall_frames(0, time.time() - 5, "t-1"))
    card = page.locator("article.alarm").first
    expect(card).to_be_visible()
    # Nothing notified while the page is in front: the nurse is looking at it.
    assert page.evaluate("window.__notices") == []

    # The newest alarm and its Acknowledge button are on the first screen, no scrolling.
    assert page.evaluate("window.scrollY") == 0
    page.screenshot(path=str(SCREENSHOTS / "nurse_board_phone.png"))
    for element in (card, card.get_by_role("button", name="Acknowledge")):
        box = element.bounding_box()
        assert box is not None and box["y"] >= 0 and box["y"] + box["height"] <= PHONE["height"], (
            box
        )
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the board is {width} px wide on a {PHONE['width']} px phone"
    page.screenshot(path=str(SCREENSHOTS / "nurse_board_phone.png"))

    # In the background (phone in the pocket), a new alarm is a system notification.
    page.evaluate("window.__hidden = true; document.dispatchEvent(new Event('visibilitychange'))")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-2", patient="P-18", location="lift 2")
        robot.stream(fall_frames(1000, time.time() - 5, "t-2"))
    _wait(lambda: page.evaluate("() => window.__notices.length") >= 1, "a system notification")
    (notice,) = page.evaluate("window.__notices")
    assert notice["title"] == "Emergency – robot robot-a"
    assert notice["body"] == "patient P-18 at lift 2"
    assert notice["requireInteraction"] is True and notice["via"] == "service worker"

    # Acknowledged from the phone.
    page.evaluate("window.__hidden = false")
    newest_id = page.locator("article.alarm").first.get_attribute("data-alarm-id")
    newest = page.locator(f"article.alarm[data-alarm-id='{newest_id}']")
    newest.get_by_role("button", name="Acknowledge").click()
    expect(newest).to_have_attribute("data-state", "acknowledged")


def test_the_web_app_manifest_and_icons_are_served(live_server):
    index = httpx.get(f"{live_server.base_url}/nurse", timeout=10).text
    assert '<link rel="manifest" href="/manifest.webmanifest"' in index
    manifest = httpx.get(f"{live_server.base_url}/manifest.webmanifest", timeout=10)
    assert manifest.status_code == 200
    body = json.loads(manifest.text)
    assert body["start_url"] == "/nurse" and body["display"] == "standalone"
    sizes = set()
    for icon in body["icons"]:
        response = httpx.get(f"{live_server.base_url}{icon['src']}", timeout=10)
        assert response.status_code == 200 and response.content[:8] == b"\x89PNG\r\n\x1a\n"
        width = int.from_bytes(response.content[16:20], "big")
        assert icon["sizes"] == f"{width}x{width}"
        sizes.add(width)
    assert {192, 512} <= sizes  # what browsers need to offer "install"
    worker = httpx.get(f"{live_server.base_url}/sw.js", timeout=10)
    assert worker.status_code == 200 and "notificationclick" in worker.text
