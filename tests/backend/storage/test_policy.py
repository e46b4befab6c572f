"""The retention policy on crafted data: alarm windows, labelled and split videos, a registered
model's lineage, imported recordings and the midnight boundary; a dry run drops nothing and
predicts exactly what the run then drops."""

from __future__ import annotations

import numpy as np
import pytest
from sqlalchemy import func, select

from backend.db import transaction
from backend.models import Frame, RetentionRun, Split
from backend.storage import policy, queries
from backend.storage.policy import DAY_S, RetentionPolicy
from backend.storage.retention import run_retention
from tests.backend.storage import factories as f

OLD_DAY = f.CUTOFF_DAY - 10 * DAY_S  # a day well past retention


def seconds(start: float, n: int, step: float = 1.0) -> list[float]:
    return [start + i * step for i in range(n)]


def crafted(session):
    t = OLD_DAY + 9 * 3600
    plain = f.robot_video(session, "r1-plain", "r1", seconds(t, 300))
    f.alarm(session, "r1", t + 100, t + 110)  # keeps t+40 .. t+140
    labelled = f.robot_video(session, "r1-labelled", "r1", seconds(t + 1000, 50), first_seq=1000)
    f.label(session, labelled, 10, 12)
    split = f.robot_video(session, "r2-split", "r2", seconds(t, 40), split=Split.TRAIN)
    lineage = f.robot_video(session, "r2-lineage", "r2", seconds(t + 500, 40), first_seq=500)
    f.model_trained_on(session, ["r2-lineage"])
    # Midnight: the last tenth of a second of the day before the cutoff's day goes, the first
    # frame of the cutoff's day (exactly midnight) and the rest of that day stay.
    midnight = f.robot_video(
        session,
        "r3-midnight",
        "r3",
        [f.CUTOFF_DAY - 0.1, f.CUTOFF_DAY, f.CUTOFF_DAY + 0.1, f.CUTOFF_DAY + 3600],
    )
    recent = f.robot_video(session, "r3-recent", "r3", seconds(f.NOW - 3600, 20), first_seq=100)
    imported = f.robot_video(session, "urfd/adl-01", None, seconds(0.0, 30, 1 / 30))
    return plain, labelled, split, lineage, midnight, recent, imported


def test_reasons_on_crafted_data(database_url, session_factory):
    with transaction(session_factory) as session:
        plain, labelled, split, lineage, midnight, recent, imported = crafted(session)
        facts = queries.policy_facts(session, RetentionPolicy(days=30), f.NOW)
    assert facts.cutoff == f.CUTOFF_DAY
    t = OLD_DAY + 9 * 3600
    assert facts.reason(plain.id, "r1", t + 39, 39) is None
    assert facts.reason(plain.id, "r1", t + 40, 40) == policy.ALARM_WINDOW
    assert facts.reason(plain.id, "r1", t + 140, 140) == policy.ALARM_WINDOW
    assert facts.reason(plain.id, "r1", t + 141, 141) is None
    assert facts.reason(plain.id, "r2", t + 100, 100) is None  # the alarm was r1's
    assert facts.reason(labelled.id, "r1", t + 1000, 0) == policy.LABELLED
    assert facts.reason(split.id, "r2", t, 0) == policy.SPLIT
    assert facts.reason(lineage.id, "r2", t + 500, 0) == policy.LINEAGE
    assert facts.reason(midnight.id, "r3", f.CUTOFF_DAY - 0.1, 0) is None
    assert facts.reason(midnight.id, "r3", f.CUTOFF_DAY, 1) == policy.RECENT
    assert facts.reason(recent.id, "r3", f.NOW - 3600, 0) == policy.RECENT
    assert facts.reason(imported.id, None, 0.0, 0) == policy.NOT_ROBOT


def test_dry_run_predicts_the_run_and_every_kept_frame_stays(database_url, session_factory):
    with transaction(session_factory) as session:
        crafted(session)
        before = f.frame_rows(session)
        facts = queries.policy_facts(session, RetentionPolicy(days=30), f.NOW)
    expected_kept = {i for i, (v, r, ts, idx) in before.items() if facts.reason(v, r, ts, idx)}
    dropped = len(before) - len(expected_kept)
    assert dropped == 300 - 101 + 1  # plain's frames outside the alarm window, one at midnight

    dry = run_retention(session_factory, f.policy_settings(), dry_run=True, now=f.NOW)
    assert dry["dropped_frames"] == dropped
    with transaction(session_factory) as session:
        assert session.scalar(select(func.count()).select_from(Frame)) == len(before)

    done = run_retention(session_factory, f.policy_settings(), now=f.NOW)
    assert done["dropped_frames"] == dropped
    assert done["kept"] == {"alarm_window": 101, "labelled": 50, "split": 40, "lineage": 40}
    with transaction(session_factory) as session:
        after = f.frame_rows(session)
        runs = session.scalars(select(RetentionRun).order_by(RetentionRun.id)).all()
    assert set(after) == expected_kept  # row by row
    assert [(r.dry_run, r.status, r.dropped_frames) for r in runs] == [
        (True, "done", dropped),
        (False, "done", dropped),
    ]
    assert (
        runs[1].dropped_bytes > 0 and sum(d["dropped"] for d in runs[1].by_day.values()) == dropped
    )


def test_downsampled_copy_keeps_every_step_th_frame_for_more_days(database_url, session_factory):
    with transaction(session_factory) as session:
        t = OLD_DAY + 3600
        video = f.robot_video(session, "r4-ten-hz", "r4", seconds(t, 100, 0.1), fps=10.0)
    settings = f.policy_settings(retention_downsample_fps=1.0, retention_downsample_days=60)
    result = run_retention(session_factory, settings, now=f.NOW)
    assert result["kept"] == {"downsampled": 10}
    with transaction(session_factory) as session:
        kept = session.scalars(select(Frame.index).where(Frame.video_id == video.id)).all()
    assert sorted(kept) == list(range(0, 100, 10))
    # Past the downsampled copy's days it goes too.
    later = f.NOW + 61 * DAY_S
    assert run_retention(session_factory, settings, now=later)["dropped_frames"] == 10


def _reasons_both_ways(facts: policy.PolicyFacts, frames: list[tuple]) -> tuple[list, list]:
    """(row by row `reason`, vectorised `reasons` decoded) of (video, robot, ts, index) rows."""
    video_ids, robot_ids, ts, index = (list(c) for c in zip(*frames, strict=True))
    codes = facts.reasons(np.array(video_ids), robot_ids, np.array(ts), np.array(index))
    return [facts.reason(*frame) for frame in frames], [policy.REASON_CODES[c] for c in codes]


def test_vectorised_reasons_equal_row_by_row_on_crafted_facts():
    """`PolicyFacts.reasons` (numpy, what the runs use) gives exactly `reason` for every frame:
    alarm windows (edges, merged, another robot's), labelled / split / lineage videos, imported
    frames, the cutoff's midnight, and the downsampled copy's step and horizon."""
    rule = RetentionPolicy(
        days=30, alarm_before_s=60, alarm_after_s=30, downsample_fps=1.0, downsample_days=5
    )
    now = f.NOW
    windows = policy.alarm_intervals(
        [
            ("r1", OLD_DAY + 100, OLD_DAY + 110, 0.0),
            ("r1", OLD_DAY + 150, None, OLD_DAY + 150),
            ("r1", None, None, OLD_DAY + 5000),
            ("r2", f.CUTOFF_DAY - 10, f.CUTOFF_DAY - 5, 0.0),
        ],
        rule,
    )
    facts = policy.PolicyFacts(
        rule,
        now,
        {7: policy.LABELLED, 8: policy.SPLIT, 9: policy.LINEAGE},
        windows,
        {1: 10, 2: 3, 7: 10},
    )
    cutoff = facts.cutoff
    edges = [
        OLD_DAY + 40 - 1e-9,
        OLD_DAY + 40,
        OLD_DAY + 140,
        OLD_DAY + 180,
        OLD_DAY + 180.001,
        OLD_DAY + 4940,
        OLD_DAY + 5030,
        OLD_DAY + 5030.5,
        cutoff - 0.1,
        cutoff - 1e-6,
        cutoff,
        cutoff + 0.1,
        cutoff - 70,
        cutoff - 75,
        cutoff - 35,
        rule.downsample_until(now) - 0.1,
        rule.downsample_until(now),
        now,
    ]
    rng = np.random.default_rng(3)
    times = edges + list(rng.uniform(OLD_DAY - 7 * DAY_S, now, 3000))
    times += list(OLD_DAY + rng.uniform(0, 6000, 2000))  # dense around r1's alarms
    frames = []
    for k, ts in enumerate(times):
        robot = [None, "r1", "r2", "r3"][k % 4]
        video = [1, 2, 3, 7, 8, 9][k % 6]
        frames.append((video, robot, float(ts), int(rng.integers(0, 40))))
    by_row, vectorised = _reasons_both_ways(facts, frames)
    assert vectorised == by_row
    assert set(by_row) == {None, *policy.REASON_CODES[1:]}  # every reason is exercised
    # The midnight of the cutoff's day: the last moment before it goes, midnight itself stays.
    midnight = [(1, "r3", cutoff - 1e-6, 7), (1, "r3", cutoff, 7)]  # not a 10th frame
    assert _reasons_both_ways(facts, midnight) == ([None, policy.RECENT], [None, policy.RECENT])
    # No facts at all, and no frames.
    bare = policy.PolicyFacts(RetentionPolicy(), now, {}, {}, {})
    assert _reasons_both_ways(bare, frames[:50])[1] == _reasons_both_ways(bare, frames[:50])[0]
    assert len(bare.reasons(np.zeros(0), [], np.zeros(0), np.zeros(0))) == 0


def test_vectorised_reasons_equal_row_by_row_on_stored_frames(database_url, session_factory):
    with transaction(session_factory) as session:
        crafted(session)
        before = f.frame_rows(session)
        facts = queries.policy_facts(session, RetentionPolicy(days=30), f.NOW)
    by_row, vectorised = _reasons_both_ways(facts, list(before.values()))
    assert vectorised == by_row


def test_a_second_retention_run_refuses_while_one_holds_the_lock(database_url, session_factory):
    """Two workers never run retention at once (on PostgreSQL an advisory lock, on SQLite a
    file lock): the second says why and drops nothing; once the first is done it runs."""
    from backend.leadership import lock_for
    from backend.storage.retention import RetentionBusy

    with transaction(session_factory) as session:
        crafted(session)
        before = f.frame_rows(session)
    running = lock_for(database_url, "retention")  # the first run, in another worker
    assert running.try_acquire()
    try:
        with pytest.raises(RetentionBusy, match="another retention run is in progress"):
            run_retention(session_factory, f.policy_settings(), now=f.NOW)
        with transaction(session_factory) as session:
            assert f.frame_rows(session) == before
            assert session.scalar(select(func.count()).select_from(RetentionRun)) == 0
    finally:
        running.release()
    assert run_retention(session_factory, f.policy_settings(), now=f.NOW)["dropped_frames"] > 0
