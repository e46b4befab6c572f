"""Browser-test fixtures: the real backend (uvicorn subprocess, throwaway SQLite database after
`alembic upgrade head`), the built frontend, and Debian Chromium driven by Playwright."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from backend.db import make_engine, make_session_factory

from .live_server import CHROMIUM, CHROMIUM_ARGS, TABLET, LiveServer, build_frontend


@pytest.fixture(scope="session")
def frontend_dist() -> Path:
    return build_frontend()


@pytest.fixture
def live_server(tmp_path, frontend_dist) -> Iterator[LiveServer]:
    server = LiveServer.create(tmp_path, frontend_dist)
    server.start()
    yield server
    server.stop()


@pytest.fixture(scope="session")
def chromium():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS
        )
        yield browser
        browser.close()


@pytest.fixture
def page(chromium):
    """A page that fails its test on any JavaScript error or console error, but the network's
    own reports of a refused request or a dropped socket, which flows under test provoke."""
    context = chromium.new_context(viewport=TABLET)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(f"page error: {error}"))
    page.on(
        "console",
        lambda message: (
            errors.append(f"console: {message.text}")
            if message.type == "error" and not EXPECTED_CONSOLE.search(message.text)
            else None
        ),
    )
    yield page
    context.close()
    assert errors == [], "errors in the browser console"


#: Chromium reports every 4xx/5xx answer and every failed socket on the console; the pages
#: handle those (the tests check what the user sees), so they are not errors of the page.
EXPECTED_CONSOLE = re.compile(
    r"Failed to load resource|WebSocket connection to .* failed|net::ERR_"
)


@pytest.fixture
def db(live_server):
    engine = make_engine(live_server.database_url)
    yield make_session_factory(engine)
    engine.dispose()
