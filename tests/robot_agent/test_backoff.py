import random

import pytest

from robot_agent.backoff import Backoff


def test_delays_double_up_to_the_cap_with_jitter_below_the_ceiling():
    backoff = Backoff(initial=0.5, maximum=8.0, jitter=0.5, rng=random.Random(1))
    ceilings, delays = [], []
    for _ in range(8):
        ceilings.append(backoff.ceiling())
        delays.append(backoff.next_delay())
    assert ceilings == [0.5, 1.0, 2.0, 4.0, 8.0, 8.0, 8.0, 8.0]
    for ceiling, delay in zip(ceilings, delays, strict=True):
        assert ceiling * 0.5 <= delay <= ceiling
    assert len({round(d, 6) for d in delays[4:]}) > 1  # jittered, not lock-step


def test_reset_after_a_good_connection_starts_small_again():
    backoff = Backoff(initial=1.0, maximum=30.0, jitter=0.0)
    for _ in range(5):
        backoff.next_delay()
    assert backoff.next_delay() == 30.0
    backoff.reset()
    assert backoff.next_delay() == 1.0


def test_fleet_jitter_spreads_reconnects():
    delays = [Backoff(initial=2.0, rng=random.Random(seed)).next_delay() for seed in range(20)]
    assert max(delays) - min(delays) > 0.3


@pytest.mark.parametrize("kwargs", [{"initial": 0}, {"initial": 5, "maximum": 1}, {"jitter": 1}])
def test_bad_parameters_are_refused(kwargs):
    with pytest.raises(ValueError):
        Backoff(**kwargs)
