import math

import numpy as np

from bench.fall_onset import compare_drops, drop_within, fastest_drop

TIMES = np.arange(40) / 30.0  # 30 frames/s


def _descent(start: int, metres_per_frame: float) -> np.ndarray:
    """Standing at 1.7 m, going down from frame `start` at a steady pace."""
    frames = np.arange(len(TIMES))
    return 1.7 - metres_per_frame * np.clip(frames - start, 0, None)


def test_drop_within_measures_the_window_from_its_start():
    height = _descent(10, 0.01)
    assert math.isclose(drop_within(height, TIMES, 10, 0.2), 0.05, abs_tol=1e-9)  # 5 of 6 frames
    assert math.isclose(drop_within(height, TIMES, 20, 0.2), 0.06, abs_tol=1e-9)
    assert math.isclose(drop_within(height, TIMES, 0, 0.2), 0.0, abs_tol=1e-9)


def test_drop_within_ignores_a_one_frame_glitch_and_the_stream_end():
    height = np.full(len(TIMES), 1.7)
    height[16] = 0.9
    assert math.isclose(drop_within(height, TIMES, 10, 0.2), 0.0, abs_tol=1e-9)
    assert math.isnan(drop_within(height, TIMES, 35, 0.2))


def test_drop_within_skips_unknown_heights():
    height = _descent(0, 0.01)
    height[:3] = np.nan
    assert math.isnan(drop_within(height, TIMES, 1, 0.2))
    # the start's median over the known frames 3 and 4 (1.67, 1.66)
    assert math.isclose(drop_within(height, TIMES, 4, 0.2), 0.055, abs_tol=1e-9)


def test_fastest_drop_finds_the_fastest_stretch():
    height = _descent(5, 0.005)
    height[25:] = height[24] - 0.03 * np.arange(1, len(TIMES) - 24)
    assert fastest_drop(height, TIMES, 0.2) > 0.15
    assert fastest_drop(np.full(len(TIMES), 1.7), TIMES, 0.2) == 0.0


def test_compare_drops_counts_both_ways():
    fall_drops = {0.2: [0.05, 0.1, 0.3, float("nan")]}
    adl_fastest = {0.2: [0.08, 0.2, 0.4]}
    result = compare_drops(fall_drops, adl_fastest)["0.2"]
    assert result == {
        "median_fall_drop_m": 0.1,
        "adl_dropping_as_far": 2,
        "adl_fastest_drop_min_m": 0.08,
        "falls_dropping_less": 1,
    }
