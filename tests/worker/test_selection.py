import numpy as np
import pytest

from vigil.classes import TransportMode
from worker.training.data import FrameData
from worker.training.selection import (
    ONSET_BINS_S,
    StreamScores,
    evaluate_folds,
    operating_curve,
)

FPS = 10
N = 30


def _crafted_stream() -> StreamScores:
    """A fall labelled Emergency from 1.0 s and scored high from 1.2 s, and a daily activity with
    one 0.2 s burst scored 0.4."""
    times = np.arange(N) / FPS
    fall_target = (np.arange(N) >= 10).astype(int)
    fall_score = np.where(np.arange(N) >= 12, 0.9, 0.05)
    adl_score = np.where((np.arange(N) >= 5) & (np.arange(N) <= 7), 0.4, 0.05)
    emergency = np.concatenate([fall_score, adl_score])
    data = FrameData(
        names=["fall-x", "adl-x"],
        is_positive_sequence=np.array([True, False]),
        features=np.zeros((2 * N, 1), np.float32),
        target=np.concatenate([fall_target, np.zeros(N, int)]),
        group=np.repeat([0, 1], N),
        timestamps=np.concatenate([times, times]),
        usable=np.ones(2 * N, bool),
        mode=TransportMode.WALKING,
        data_sha256="crafted",
    )
    return StreamScores(data, np.array([0, 1]), np.stack([1 - emergency, emergency], axis=1))


def test_operating_curve_reports_each_fixed_operating_point():
    curve = operating_curve([_crafted_stream()], (0.3, 0.5), (0.1, 0.3))
    points = {(p["threshold"], p["delay_ms"]): p for p in curve}
    assert sorted(points) == [(0.3, 100), (0.3, 300), (0.5, 100), (0.5, 300)]
    # The 0.2 s burst outlasts a 0.1 s delay but not a 0.3 s one, and stays below 0.5.
    assert points[0.3, 100]["adl_false_alarms"] == 1
    assert points[0.3, 300]["adl_false_alarms"] == 0
    assert points[0.5, 100]["adl_false_alarms"] == 0
    for point in curve:
        assert point["falls_detected"] == point["falls_total"] == 1
        assert point["adl_total"] == 1
        # Scored high from 0.2 s after the first Emergency frame, raised after the delay.
        expected = 0.2 + point["delay_ms"] / 1000
        assert point["median_time_to_alarm_s"] == pytest.approx(expected)
        assert point["frame_recall"] == pytest.approx(18 / 20)


def test_operating_curve_pools_streams():
    stream = _crafted_stream()
    (point,) = operating_curve([stream, stream], (0.3,), (0.1,))
    assert (point["falls_total"], point["adl_total"], point["adl_false_alarms"]) == (2, 2, 2)


def test_recall_by_onset_bins_missed_emergency_frames_by_time_since_the_first_label():
    # Emergency from 1.0 s, scored high from 1.2 s: the frames at 1.0 and 1.1 s are missed.
    result = evaluate_folds([(_crafted_stream(), 0.5, 0.1)])
    bins = {(row["from_s"], row["to_s"]): row for row in result["recall_by_onset"]}
    assert [key[0] for key in bins] == list(ONSET_BINS_S[:-1])
    assert (bins[0.0, 0.2]["emergency_frames"], bins[0.0, 0.2]["missed"]) == (2, 2)
    assert (bins[0.2, 0.4]["emergency_frames"], bins[0.2, 0.4]["missed"]) == (2, 0)
    assert bins[1.0, None]["emergency_frames"] == 10
    assert sum(row["emergency_frames"] for row in bins.values()) == 20
    missed = sum(row["missed"] for row in bins.values())
    assert missed == result["fn"]
    # The daily activity's burst is not an Emergency frame and counts nowhere here.
    assert result["frame_recall"] == pytest.approx(1 - missed / 20)
