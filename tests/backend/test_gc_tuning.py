"""The backend freezes its start-up heap and collects young objects less often while it runs,
and puts the collector back as it was when it stops (tests run many apps in one process)."""

from __future__ import annotations

import gc

from fastapi.testclient import TestClient

from backend.gc_tuning import COLLECT_AFTER
from backend.main import create_app


def test_collector_is_tuned_while_the_app_runs_and_restored_after(settings):
    before = gc.get_threshold()
    with TestClient(create_app(settings)):
        assert gc.get_threshold() == COLLECT_AFTER
        assert gc.get_freeze_count() > 10_000
    assert gc.get_threshold() == before
    assert gc.get_freeze_count() == 0
