"""bench.ingest's fleet run twice over the same SQLite database, through the real backend (as
bench.storage does: with the history, then again during retention). The second run's robots
must number their frames after the welcome's last_seq, like the real agent: frames re-sent under
numbers the backend already has are acknowledged but neither stored nor alarmed on, which made
the second run's alarm latency look like the time to pass the first run's high-water mark."""

import pytest

from bench import ingest, storage

pytestmark = pytest.mark.slow


def test_a_second_fleet_run_over_the_same_database_is_measured_like_the_first(tmp_path):
    # 3 robots at 10 Hz, every 5th frame an Emergency; the second run shorter than the first,
    # so counting the whole table instead of this run's frames would not come out at 0 lost.
    first = ingest.RunConfig("sqlite", 3, 10, 1, 3.0, 50, 5)
    second = ingest.RunConfig("sqlite", 3, 10, 1, 2.0, 50, 5)
    url, drop = ingest._prepare_database("sqlite", tmp_path, first.robots)
    try:
        runs = [storage.ingest_run(url, config, tmp_path) for config in (first, second)]
    finally:
        drop()
    for i, run in enumerate(runs):
        print(f"run {i + 1}: {run}")
    for run in runs:
        assert run["emergencies_sent"] > 0
        assert run["emergencies_pushed"] == run["emergencies_sent"]
        assert run["alarm_p99_ms"] < 2000
        assert run["frames_lost"] == 0
        assert run["duplicates"] == 0
