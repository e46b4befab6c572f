import numpy as np

from vigil.events import DELAY_GRID_S, SequenceEvent, alarm_times_over_delays, summarise
from vigil.policy import alarm_mask, apply_delay


def test_event_definitions():
    # alarm 0.4 s before the first Emergency frame still counts as the detection
    early_ok = SequenceEvent("fall-a", True, first_emergency_s=2.0, alarm_times_s=(1.6,))
    assert early_ok.detected and not early_ok.false_alarm
    assert abs(early_ok.time_to_alarm_s + 0.4) < 1e-9
    # an alarm 0.6 s before is a false alarm; a later one is the detection
    too_early = SequenceEvent("fall-b", True, first_emergency_s=2.0, alarm_times_s=(1.4, 2.3))
    assert too_early.false_alarm and too_early.detected
    assert abs(too_early.time_to_alarm_s - 0.3) < 1e-9
    missed = SequenceEvent("fall-c", True, first_emergency_s=2.0, alarm_times_s=(1.0,))
    assert not missed.detected and missed.false_alarm
    adl = SequenceEvent("adl-a", False, None, alarm_times_s=(5.0,))
    quiet = SequenceEvent("adl-b", False, None, alarm_times_s=())
    summary = summarise([early_ok, too_early, missed, adl, quiet])
    assert summary["falls_detected"] == 2 and summary["falls_total"] == 3
    assert summary["adl_false_alarms"] == 1 and summary["adl_total"] == 2
    assert abs(summary["median_time_to_alarm_s"] + 0.05) < 1e-9


def test_delay_sweep_matches_the_filter_for_every_delay():
    rng = np.random.default_rng(5)
    raw = (rng.random(600) < 0.3).astype(int)
    raw[100:160] = 1
    t = np.cumsum(rng.uniform(0.02, 0.05, 600))
    swept = alarm_times_over_delays(raw == 1, t)
    for k, delay in enumerate(DELAY_GRID_S):
        filtered = apply_delay(raw, t, delay)
        assert swept[k] == t[alarm_mask(filtered, 1)].tolist(), delay
