"""The on-robot behaviour state machine (robot_agent.behaviour), driven by decisions."""

from __future__ import annotations

import pytest

from robot_agent.behaviour import BEHAVIOUR, Behaviour, BehaviourState
from vigil.classes import Decision, TransportMode
from vigil.states import IllegalTransition

N, P, E = Decision.NORMAL, Decision.PAUSE, Decision.EMERGENCY


def feed(behaviour: Behaviour, decisions, start=0.0, step=0.1, **kw):
    changes = []
    for i, decision in enumerate(decisions):
        change = behaviour.update(decision, start + i * step, transport_id="t-1", **kw)
        if change is not None:
            changes.append(change)
    return changes


def test_pause_resumes_only_after_normal_for_the_hold_time():
    behaviour = Behaviour(TransportMode.WHEELCHAIR, hold_s=2.0)
    seen = []
    behaviour.listeners.append(seen.append)
    feed(behaviour, [N, N, P])
    assert behaviour.state == BehaviourState.PAUSED
    # 1.9 s of Normal, then a Pause again: the hold starts over
    feed(behaviour, [N] * 20 + [P], start=1.0)
    assert behaviour.state == BehaviourState.PAUSED
    feed(behaviour, [N] * 20, start=10.0)  # 10.0 .. 11.9: not yet 2 s
    assert behaviour.state == BehaviourState.PAUSED
    feed(behaviour, [N], start=12.0)  # 2.0 s of Normal
    assert behaviour.state == BehaviourState.TRANSPORTING
    assert [c.state for c in seen] == ["paused", "transporting"]
    assert seen[0].transport_id == "t-1" and seen[1].since == 12.0


def test_pause_in_walking_mode_does_not_pause():
    behaviour = Behaviour(TransportMode.WALKING)
    feed(behaviour, [P, P, P])
    assert behaviour.state == BehaviourState.TRANSPORTING


@pytest.mark.parametrize("mode", list(TransportMode))
def test_emergency_stops_in_every_mode_and_never_resumes_by_itself(mode):
    behaviour = Behaviour(mode, hold_s=0.5)
    feed(behaviour, [N, E])
    assert behaviour.state == BehaviourState.EMERGENCY_STOP
    feed(behaviour, [N] * 200 + [None] * 50, start=5.0)
    assert behaviour.state == BehaviourState.EMERGENCY_STOP
    change = behaviour.resolved(alarm_id=7, by="nurse1")
    assert behaviour.state == BehaviourState.TRANSPORTING
    assert "nurse1" in change.reason


def test_local_reset_releases_and_is_kept_for_the_backend():
    behaviour = Behaviour(TransportMode.WALKING)
    assert behaviour.reset() is None  # nothing to reset
    feed(behaviour, [E])
    behaviour.reset(ts=123.0)
    assert behaviour.state == BehaviourState.TRANSPORTING
    assert behaviour.resets == [(123.0, "t-1", None, "local")]


def test_degraded_detection_slows_or_stops_and_recovers():
    behaviour = Behaviour(TransportMode.WALKING, degraded_action="slow", unseen_s=1.0)
    feed(behaviour, [None])
    assert behaviour.state == BehaviourState.DETECTION_DEGRADED
    assert "slow" in behaviour.reason
    feed(behaviour, [N])
    assert behaviour.state == BehaviourState.TRANSPORTING
    feed(behaviour, [N] * 9, seen=False)  # 0.8 s unseen
    assert behaviour.state == BehaviourState.TRANSPORTING
    feed(behaviour, [N] * 11, seen=False)
    assert behaviour.state == BehaviourState.DETECTION_DEGRADED
    assert "patient not seen" in behaviour.reason
    feed(behaviour, [N], degraded="model m failed its check")
    assert behaviour.state == BehaviourState.DETECTION_DEGRADED
    feed(behaviour, [E])  # an Emergency still stops
    assert behaviour.state == BehaviourState.EMERGENCY_STOP


def test_machine_refuses_leaving_emergency_stop_by_resume():
    behaviour = Behaviour(TransportMode.WALKING)
    feed(behaviour, [E])
    with pytest.raises(IllegalTransition, match="cannot resume"):
        BEHAVIOUR.act(behaviour, "resume")


def test_a_release_names_the_alarm_it_ends():
    behaviour = Behaviour(TransportMode.WALKING)
    feed(behaviour, [Decision.EMERGENCY])
    released = behaviour.resolved(alarm_id=7, by="nurse:nina")
    assert (released.state, released.alarm_id) == (BehaviourState.TRANSPORTING, 7)
    assert behaviour.alarm_id is None  # on no alarm any more
    feed(behaviour, [Decision.EMERGENCY])
    behaviour.acknowledged(8, "nurse:nina", 0.0)
    assert behaviour.reset(who="cli").alarm_id == 8
