"""SQLite retention deletes in bounded chunks (incremental vacuum between them) while an ingest
writes: every ingested frame is there afterwards, and exactly the frames the policy drops are
gone. The chunk size adapts so that each chunk holds the write lock for about
retention_chunk_hold_ms (`ChunkSizer`)."""

from __future__ import annotations

import threading
import time

from backend.db import Base, make_engine, make_session_factory, transaction
from backend.ingest.bulk import insert_frame_rows
from backend.storage import queries, retention
from backend.storage.policy import DAY_S, RetentionPolicy
from backend.storage.retention import ChunkSizer, run_retention
from tests.backend.storage import factories as f


def test_chunk_sizer_converges_on_the_hold_target():
    """A chunk costing 0.05 ms a row with a 30 ms target settles at 600 rows, from above and
    from below, moving at most by a factor of 2 per chunk."""
    for start in (20_000, 10):
        sizer = ChunkSizer(start, target_ms=30, min_rows=5)
        sizes = [sizer.rows]
        for _ in range(30):
            sizes.append(sizer.update(sizer.rows, hold_ms=0.05 * sizer.rows))
        assert sizes[-1] == 600
        assert all(b <= 2 * a and a <= 2 * b for a, b in zip(sizes, sizes[1:], strict=False))
    # A fixed overhead per chunk (the commit, the vacuum) keeps it larger: still near target.
    sizer = ChunkSizer(100, target_ms=30)
    for _ in range(40):
        sizer.update(sizer.rows, hold_ms=10 + 0.01 * sizer.rows)
    assert abs(10 + 0.01 * sizer.rows - 30) < 3


def test_chunk_sizer_bounds_and_edge_cases():
    assert ChunkSizer(0, 30, min_rows=20).rows == 20
    assert ChunkSizer(10**9, 30, max_rows=1000).rows == 1000
    sizer = ChunkSizer(100, 30, min_rows=20, max_rows=150)
    assert sizer.update(100, 0.0) == 150  # too quick to measure: grow (bounded)
    assert sizer.update(150, 10_000) == 75  # one very slow chunk: halve, not collapse
    assert sizer.update(0, 5.0) == 75  # the last, empty chunk changes nothing
    for _ in range(10):
        sizer.update(sizer.rows, 10_000)
    assert sizer.rows == 20


def test_chunked_retention_racing_an_ingest_loses_nothing(tmp_path, monkeypatch):
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

    chunks: list[tuple[int, float, int]] = []  # (rows, hold ms, next chunk's rows)
    update = ChunkSizer.update

    def spy(sizer: ChunkSizer, rows_done: int, hold_ms: float) -> int:
        chunks.append((rows_done, hold_ms, update(sizer, rows_done, hold_ms)))
        return chunks[-1][2]

    monkeypatch.setattr(retention.ChunkSizer, "update", spy)
    writer = threading.Thread(target=ingest)
    writer.start()
    try:
        # The first chunk is far too large for a 1 ms hold: the next ones shrink.
        settings = f.policy_settings(
            retention_chunk_rows=1000, retention_chunk_pause_ms=1, retention_chunk_hold_ms=1
        )
        result = run_retention(factory, settings, now=f.NOW)
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
    # Adaptive chunks: after the first, sizes follow the measured holds (shrinking here).
    assert chunks[0][0] == 1000 and len(chunks) >= 4
    assert max(rows for rows, _, _ in chunks[1:]) < 1000
    # (the last chunk is the data's rest, not a full one)
    assert all(nxt == ChunkSizer(rows, 1).update(rows, hold) for rows, hold, nxt in chunks[:-1])
