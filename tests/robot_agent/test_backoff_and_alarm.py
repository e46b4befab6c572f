import random

from robot_agent.client import Backoff, LocalAlarm


def test_backoff_doubles_up_to_the_cap_and_resets():
    backoff = Backoff(base_s=0.1, cap_s=1.0, jitter=False)
    assert [round(backoff.next_delay(), 3) for _ in range(6)] == [0.1, 0.2, 0.4, 0.8, 1.0, 1.0]
    backoff.reset()
    assert backoff.next_delay() == 0.1


def test_backoff_jitter_stays_within_half_and_full_ceiling():
    backoff = Backoff(base_s=1.0, cap_s=8.0, rng=random.Random(3))
    for ceiling in (1, 2, 4, 8, 8):
        assert ceiling / 2 <= backoff.next_delay() <= ceiling


def test_local_alarm_only_when_emergency_and_backend_unreachable(tmp_path):
    marker = tmp_path / "hook-ran"
    alarm = LocalAlarm("robot-x", hook_command=f"touch {marker}", grace_s=1.0)
    alarm.update(emergency_holds=True, backend_reachable=True, now=0)
    alarm.update(emergency_holds=False, backend_reachable=False, now=1)
    assert not alarm.raised
    alarm.update(emergency_holds=True, backend_reachable=False, now=2)
    assert not alarm.raised  # within the grace period
    alarm.update(emergency_holds=True, backend_reachable=False, now=3.5)
    alarm.update(emergency_holds=True, backend_reachable=False, now=4)
    assert alarm.raised and alarm.raised_count == 1
    alarm.update(emergency_holds=True, backend_reachable=True, now=5)
    assert not alarm.raised
    import time

    for _ in range(50):
        if marker.exists():
            break
        time.sleep(0.02)
    assert marker.exists()
