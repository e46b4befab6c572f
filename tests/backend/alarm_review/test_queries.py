from datetime import UTC, datetime, timedelta

from backend.alarm_review.fatigue import fatigue_stats, shift_of
from backend.alarm_review.queries import HistoryFilter, alarm_history, frames_around

from .factories import T0, alarm, robot_with_frames


def test_frames_around_covers_the_seconds_before_and_after(session):
    video = robot_with_frames(session)
    row = alarm(session, video)
    frames = frames_around(session, row, before_s=2.0, after_s=1.0)
    # first_frame_ts = index 53, last = index 69 at 10 fps: indices 33..79
    assert [f.index for f in frames] == list(range(33, 80))


def test_history_filters_and_pages(session):
    video = robot_with_frames(session)
    alarm(session, video, transport_key="a", verdict="false_alarm", state="resolved")
    alarm(
        session,
        video,
        transport_key="b",
        kind="pause",
        model_version="m2",
        raised_at=T0 + timedelta(hours=1),
    )
    alarm(session, video, transport_key="c", ward="B", raised_at=T0 + timedelta(hours=2))
    total, rows = alarm_history(session, HistoryFilter(), limit=2, offset=0)
    assert total == 3 and [r.transport_key for r in rows] == ["c", "b"]
    assert alarm_history(session, HistoryFilter(ward="B"), 10, 0)[0] == 1
    assert (
        alarm_history(session, HistoryFilter(verdict="false_alarm"), 10, 0)[1][0].transport_key
        == "a"
    )
    assert alarm_history(session, HistoryFilter(model_version="m2", kind="pause"), 10, 0)[0] == 1
    window = HistoryFilter(since=T0 + timedelta(minutes=30), until=T0 + timedelta(minutes=90))
    assert [r.transport_key for r in alarm_history(session, window, 10, 0)[1]] == ["b"]


def test_shift_boundaries():
    day = datetime(2026, 3, 2, tzinfo=UTC)
    assert shift_of(day.replace(hour=5, minute=59)) == (day - timedelta(hours=2), "night")
    assert shift_of(day.replace(hour=6)) == (day.replace(hour=6), "early")
    assert shift_of(day.replace(hour=21, minute=59)) == (day.replace(hour=14), "late")
    assert shift_of(day.replace(hour=23)) == (day.replace(hour=22), "night")


def test_fatigue_stats_counts_false_share_and_ack_time(session):
    video = robot_with_frames(session)
    ack = lambda s: T0 + timedelta(seconds=5 + s)  # noqa: E731
    alarm(session, video, transport_key="a", verdict="false_alarm", acknowledged_at=ack(10))
    alarm(session, video, transport_key="b", verdict="true_emergency", acknowledged_at=ack(30))
    alarm(session, video, transport_key="c", model_version="m2", acknowledged_at=ack(20))
    alarm(session, video, transport_key="", kind="robot_offline", model_version=None)
    until = T0 + timedelta(seconds=65)
    stats = fatigue_stats(alarm_history(session, HistoryFilter(), 100, 0)[1], until)
    [shift] = stats["shifts"]
    assert shift["shift"] == "early" and shift["alarms"] == 4 and shift["emergencies"] == 3
    assert shift["resolved"] == 2 and shift["false_alarms"] == 1
    assert (shift["acknowledged"], shift["unacknowledged"]) == (3, 1)
    # 10, 20, 30 s and the unacknowledged one waiting 60 s until the period's end
    assert shift["median_ack_s"] == 25.0
    m1, m2 = stats["by_model"]
    assert (m1["model_version"], m1["alarms"], m1["false_share"], m1["median_ack_s"]) == (
        "m1",
        2,
        0.5,
        20.0,
    )
    assert (m2["model_version"], m2["false_share"]) == ("m2", None)
    assert (m1["acknowledged"], m1["unacknowledged"], m1["resolved"]) == (2, 0, 2)
