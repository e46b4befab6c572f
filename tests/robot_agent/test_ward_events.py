"""The simulated fleet's pace (issue 21): falls, Pause situations and look-alikes at their rates
per robot per hour, routine movement otherwise. GENERATED transports."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from robot_agent.source_factory import (
    LOOKALIKE_EVENTS,
    PAUSE_EVENTS,
    EventRates,
    generated_transports,
    ward_events,
)
from vigil.synthetic import EMERGENCY_EVENTS, Locomotion


@pytest.mark.parametrize("locomotion", ["walking", "rollator", "wheelchair"])
def test_default_rates_give_about_one_fall_per_robot_per_quarter_hour(locomotion):
    rates = EventRates()
    transport_s = 30.0
    hours = 200
    rng = np.random.default_rng(1)
    kinds = Counter()
    for _ in range(int(hours * 3600 / transport_s)):
        (event,) = ward_events(rng, locomotion, transport_s, rates)
        if event in EMERGENCY_EVENTS[Locomotion(locomotion)]:
            kinds["fall"] += 1
        elif event in PAUSE_EVENTS:
            kinds["pause"] += 1
        elif event in LOOKALIKE_EVENTS:
            kinds["lookalike"] += 1
        else:
            kinds["routine"] += 1
    falls_per_hour = kinds["fall"] / hours
    assert 3.0 <= falls_per_hour <= 6.0  # one per 10-20 min
    assert 2.0 <= kinds["pause"] / hours <= 4.0
    assert 4.5 <= kinds["lookalike"] / hours <= 7.5
    assert kinds["routine"] > 0.85 * sum(kinds.values())


def test_no_falls_when_the_rate_is_zero_and_every_transport_is_one_situation():
    rng = np.random.default_rng(2)
    quiet = EventRates(falls_per_hour=0, pauses_per_hour=0, lookalikes_per_hour=0)
    events = {e for _ in range(500) for e in ward_events(rng, "walking", 30, quiet)}
    assert events <= {"turning", "gesturing", "standing"}
    plans = generated_transports(
        seed=5, count=2, duration_s=8, rates=EventRates(falls_per_hour=450)
    )
    for plan in plans:  # 450/h over 8 s transports: every transport a fall
        (event,) = plan.observations.events
        assert event in EMERGENCY_EVENTS[Locomotion.WALKING]
        assert plan.generated_events == (event,)  # the ground truth the agent logs
