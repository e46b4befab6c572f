"""SQLite retention deletes in bounded chunks (incremental vacuum between them) while an ingest
writes: every ingested frame is there afterwards, and exactly the frames the policy drops are
gone."""

from __future__ import annotations

import threading
import time

from backend.db import Base, make_engine, make_session_factory, transaction
from backend.ingest.bulk import insert_frame_rows
from backend.storage import queries
from backend.storage.policy import DAY_S, RetentionPolicy
from backend.storage.retention import run_retention
from tests.backend.storage import factories as f


def test_chunked_retention_racing_an_ingest_loses_nothing(tmp_path):
    engine = make_engine(f"sqlite:///{tmp_path / 'race.db'}")  # incremental auto-vacuum
    Base.metadata.create_all(engine)
    with engine.connect() as connection:
        assert connection.exec_driver_sql("PRAGMA auto_vacuum").scalar_one() == 2
    factory = make_session_factory(engine)
    old = f.CUTOFF_DAY - 3 * DAY_S
    with transaction(factory) as session:
        f.robot_video(session, "r1-old", "r1", [old + i * 0.1 for i in range(3000)])
        f.alarm(session, "r1", old + 100, old + 100)  # keeps 90 s: 901 frames
        live = f.robot_video(session, "r2-live", "r2", [f.NOW], first_seq=0)
        live_id = live.id
        before = f.frame_rows(session)
        facts = queries.policy_facts(session, RetentionPolicy(days=30), f.NOW)
    expected = {i for i, (v, r, ts, idx) in before.items() if facts.reason(v, r, ts, idx)}

    stop, ingested, commit_s, errors = threading.Event(), [], [], []

    def ingest() -> None:  # like the frame writer: one short transaction per batch
        seq = 1
        try:
            while not stop.is_set() or seq < 200:
                started = time.perf_counter()
                with transaction(factory) as session:
                    rows = [f.live_row(live_id, "r2", seq + k, f.NOW + seq + k) for k in range(5)]
                    insert_frame_rows(session, rows)
                commit_s.append(time.perf_counter() - started)
                ingested.extend(range(seq, seq + 5))
                seq += 5
                time.sleep(0.002)
        except Exception as error:  # reported below
            errors.append(error)

    writer = threading.Thread(target=ingest)
    writer.start()
    try:
        result = run_retention(factory, f.policy_settings(retention_chunk_rows=100,
                                                          retention_chunk_pause_ms=1),
                               now=f.NOW)  # fmt: skip
    finally:
        stop.set()
        writer.join()
    assert not errors
    with transaction(factory) as session:
        after = f.frame_rows(session)
        free = session.connection().exec_driver_sql("PRAGMA freelist_count").scalar_one()
    engine.dispose()
    live_seqs = {idx for i, (v, r, ts, idx) in after.items() if v == live_id}
    assert {0, *range(1, 1 + len(ingested))} <= live_seqs | {0}
    assert len([1 for v, *_ in after.values() if v == live_id]) == 1 + len(ingested)
    old_left = {i for i, (v, *_rest) in after.items() if v != live_id}
    assert old_left == {i for i in expected if before[i][0] != live_id}
    assert result["dropped_frames"] == 3000 - 901
    assert free < 50  # pages given back chunk by chunk (incremental vacuum)
    assert max(commit_s) < 1.0, f"an ingest commit waited {max(commit_s):.3f} s"
