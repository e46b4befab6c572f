"""The retention policy on crafted data: alarm windows, labelled and split videos, a registered
model's lineage, imported recordings and the midnight boundary; a dry run drops nothing and
predicts exactly what the run then drops."""

from __future__ import annotations

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
    midnight = f.robot_video(session, "r3-midnight", "r3",
                             [f.CUTOFF_DAY - 0.1, f.CUTOFF_DAY, f.CUTOFF_DAY + 0.1,
                              f.CUTOFF_DAY + 3600])  # fmt: skip
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
        (True, "done", dropped), (False, "done", dropped)]  # fmt: skip
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
