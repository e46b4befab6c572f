"""Browser-test fixtures: the real backend (uvicorn subprocess, throwaway SQLite database after
`alembic upgrade head`), the built frontend, and Debian Chromium driven by Playwright."""

from __future__ import annotations

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
    context = chromium.new_context(viewport=TABLET)
    page = context.new_page()
    yield page
    context.close()


@pytest.fixture
def db(live_server):
    engine = make_engine(live_server.database_url)
    yield make_session_factory(engine)
    engine.dispose()
