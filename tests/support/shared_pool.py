"""Two pytest runs side by side sharing out the tests that do not depend on the database.

`make test` runs the database tests on SQLite and, on the other core, on PostgreSQL; the tests
that touch no database (domain package, training, robot agent, browser) need to run once, on
either side. With VIGIL_TEST_POOL naming a directory that both runs share, each run first runs
its own tests, then takes the shared ones a test file at a time: a run claims a file by
creating its entry in that directory (atomic: exactly one run gets it), runs all of that file's
shared tests, and skips nothing it claimed. Whichever run is free takes the next file, so both
cores stay busy to the end. The browser files go last: Playwright's synchronous API keeps an
event loop running in the test thread for the rest of the session, and a later test calling
`asyncio.run` would fail ("cannot be called from a running event loop").

VIGIL_TEST_OWN says which tests are the run's own: `database` (the default) for the tests that
use the database fixtures, `none` for a run that only helps with the shared ones. Without
VIGIL_TEST_POOL nothing changes: a plain `pytest` runs every test itself."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Tests that use one of these fixtures depend on the database (they run on each database).
DATABASE_FIXTURES = {"migrated_database_url", "database_url"}
OWN_CHOICES = ("database", "none")


def uses_database(item: pytest.Item) -> bool:
    return bool(DATABASE_FIXTURES & set(getattr(item, "fixturenames", ())))


def pool_directory() -> Path | None:
    value = os.environ.get("VIGIL_TEST_POOL")
    return Path(value) if value else None


def own_tests() -> str:
    own = os.environ.get("VIGIL_TEST_OWN", "database")
    if own not in OWN_CHOICES:
        raise pytest.UsageError(f"VIGIL_TEST_OWN must be one of {OWN_CHOICES}, not {own!r}")
    return own


def is_shared(item: pytest.Item) -> bool:
    return item.get_closest_marker("browser") is not None or not uses_database(item)


def file_of(item: pytest.Item) -> str:
    return item.nodeid.split("::", 1)[0]


def claim(pool: Path, test_file: str) -> bool:
    """Whether this run got `test_file`: the first run to create its entry gets it."""
    try:
        (pool / test_file.replace("/", "__")).mkdir()
    except FileExistsError:
        return False
    return True


class SharedPool:
    def __init__(self, pool: Path, own: str) -> None:
        self.pool = pool
        self.own = own
        self.claimed: list[str] = []
        self.left: list[str] = []

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, config, items) -> None:
        """Own tests first, then the shared ones by file, browser files last; a run that owns
        nothing drops the database tests (the other run has them)."""
        own = [i for i in items if not is_shared(i)] if self.own == "database" else []
        if self.own == "none":
            dropped = [i for i in items if not is_shared(i)]
            if dropped:
                config.hook.pytest_deselected(items=dropped)
        shared = [i for i in items if is_shared(i)]
        shared.sort(key=lambda i: i.get_closest_marker("browser") is not None)  # stable
        items[:] = own + shared

    def runnable(self, items: list[pytest.Item]) -> Iterator[pytest.Item]:
        decided: dict[str, bool] = {}
        for item in items:
            if not is_shared(item):
                yield item
                continue
            test_file = file_of(item)
            if test_file not in decided:
                decided[test_file] = claim(self.pool, test_file)
                (self.claimed if decided[test_file] else self.left).append(test_file)
            if decided[test_file]:
                yield item

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtestloop(self, session: pytest.Session) -> bool | None:
        """pytest's own loop over the tests this run owns or claims; the next item is claimed
        before the current one runs, so each test's `nextitem` is one that really runs."""
        if session.testsfailed and not session.config.option.continue_on_collection_errors:
            raise session.Interrupted(f"{session.testsfailed} errors during collection")
        if session.config.option.collectonly:
            return True
        tests = self.runnable(session.items)
        item = next(tests, None)
        while item is not None:
            nextitem = next(tests, None)
            item.config.hook.pytest_runtest_protocol(item=item, nextitem=nextitem)
            if session.shouldfail:
                raise session.Failed(session.shouldfail)
            if session.shouldstop:
                raise session.Interrupted(session.shouldstop)
            item = nextitem
        return True

    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        """A helping run left with no shared test (e.g. PYTEST_ARGS named database tests only)
        has done its part: that is not pytest's "no tests collected" failure."""
        if self.own == "none" and exitstatus == pytest.ExitCode.NO_TESTS_COLLECTED:
            session.exitstatus = pytest.ExitCode.OK

    def pytest_terminal_summary(self, terminalreporter) -> None:
        terminalreporter.write_line(
            f"shared tests: this run took {len(self.claimed)} test files, the other run "
            f"{len(self.left)} (pool {self.pool})"
        )


def register(config: pytest.Config) -> None:
    """Called from tests/conftest.py's pytest_configure."""
    pool = pool_directory()
    if pool is not None:
        pool.mkdir(parents=True, exist_ok=True)
        config.pluginmanager.register(SharedPool(pool, own_tests()), "vigil-shared-pool")
