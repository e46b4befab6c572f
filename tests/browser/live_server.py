"""The real system for browser tests and the alarm-latency benchmark: the built frontend, the
backend as a uvicorn subprocess on a free port against a throwaway, migrated SQLite database
(tests/support/live_backend.py), and Debian Chromium options for Playwright."""

from __future__ import annotations

import fcntl
import hashlib
import os
import subprocess
import tempfile
from pathlib import Path

from tests.support.live_backend import (
    PASSWORD,
    REPO_ROOT,
    ROBOT_ID,
    ROBOT_TOKEN,
    LiveServer,
    free_port,
    prepare_database,
)

__all__ = [
    "PASSWORD",
    "REPO_ROOT",
    "SCREENSHOTS",
    "ROBOT_ID",
    "ROBOT_TOKEN",
    "LiveServer",
    "free_port",
    "prepare_database",
    "build_frontend",
    "list_alarm_ids",
    "sign_in",
]

FRONTEND = REPO_ROOT / "frontend"
#: Where browser tests save screenshots: a temporary folder, unless `make screenshots` points
#: VIGIL_SCREENSHOT_DIR at docs/screenshots (so a plain test run leaves the tree untouched).
SCREENSHOTS = Path(
    os.environ.get("VIGIL_SCREENSHOT_DIR")
    or Path(os.environ.get("TMPDIR", "/tmp")) / "vigil-screenshots"
)
CHROMIUM = os.environ.get("VIGIL_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
TABLET = {"width": 1024, "height": 768}


def _newest_mtime(paths) -> float:
    return max((p.stat().st_mtime for p in paths if p.is_file()), default=0.0)


def build_frontend() -> Path:
    """The production build in frontend/dist, rebuilt when a source file is newer than it. A
    file lock keeps two test runs side by side (`make test`) from building it at once."""
    index = FRONTEND / "dist" / "index.html"
    sources = [
        *FRONTEND.joinpath("src").rglob("*"),
        *FRONTEND.joinpath("public").rglob("*"),
        FRONTEND / "index.html",
        FRONTEND / "package.json",
        FRONTEND / "vite.config.ts",
    ]
    lock_path = Path(tempfile.gettempdir()) / f"vigil-frontend-build-{_path_key(FRONTEND)}.lock"
    with lock_path.open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not index.exists() or _newest_mtime(sources) > index.stat().st_mtime:
            if not (FRONTEND / "node_modules").is_dir():
                subprocess.run(["npm", "ci", "--no-audit", "--no-fund"], cwd=FRONTEND, check=True)
            subprocess.run(["npm", "run", "build"], cwd=FRONTEND, check=True)
    return index.parent


def _path_key(path: Path) -> str:
    return hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:12]


def sign_in(page, base_url: str, username: str = "nina", password: str = PASSWORD) -> None:
    page.goto(f"{base_url}/login")
    page.get_by_label("User name").fill(username)
    page.get_by_label("Password").fill(password)
    page.get_by_role("button", name="Sign in").click()


#: Every row of the list as a nurse reads it: scrolled through from the top, one window at a
#: time (the list draws only the rows near the window), then back to the top.
_READ_LIST = """
async () => {
  const seen = [];
  const frame = () => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  const end = () => document.documentElement.scrollHeight;
  for (let y = 0; ; y += Math.floor(window.innerHeight / 2)) {
    window.scrollTo(0, y);
    await frame();
    const rows = [...document.querySelectorAll("main.board .alarm-list [data-alarm-id]")];
    for (const r of rows)
      seen.push([parseFloat(r.style.top), Number(r.getAttribute("data-alarm-id"))]);
    if (y + window.innerHeight >= end()) break;
  }
  window.scrollTo(0, 0);
  await frame();
  // One entry per place in the list: a row seen in two windows is one row; two places, two rows.
  const byPlace = new Map(seen.map(([top, id]) => [top, id]));
  return [...byPlace.entries()].sort((a, b) => a[0] - b[0]).map(([, id]) => id);
}
"""


def list_alarm_ids(page) -> list[int]:
    """The alarm ids of the board's list view, top to bottom, as a nurse reads them by
    scrolling (the list draws only the rows near the window)."""
    return [int(x) for x in page.evaluate(_READ_LIST)]
