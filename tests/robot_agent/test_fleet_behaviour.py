"""Issue 33's fleet goal, on the simulated fleet's own pipeline (GENERATED transports, decisions
from the generator's ground truth as `vigil-robot simulate` streams them until a model is
assigned): every transport with an Emergency ends in `emergency_stop` and leaves it only by a
nurse's resolve or a local reset; in wheelchair mode every Pause situation pauses the robot and
it resumes once the patient is back to Normal for the hold time."""

from __future__ import annotations

import pytest

from robot_agent.behaviour import Behaviour, BehaviourState
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.source_factory import PAUSE_EVENTS, EventRates, generated_transports
from vigil.classes import Decision, TransportMode
from vigil.taxonomy import DEFAULT_TAXONOMY

TRANSPORTS = 6
# Situations several times an hour more often than a ward's default, so a few transports hold
# every kind: falls, Pause situations, look-alikes.
RATES = EventRates(falls_per_hour=120, pauses_per_hour=240, lookalikes_per_hour=120)


def _run(tmp_path, mode: TransportMode, locomotion: str, seed: int, events=None, count=TRANSPORTS):
    pipeline = Pipeline(
        Outbox(tmp_path / f"{locomotion}-{seed}.sqlite", 50_000_000),
        mode,
        None,
        ground_truth_fallback=True,
        available_inputs=["keypoints", "depth", "floor"],
    )
    behaviour = pipeline.behaviour = Behaviour(mode, hold_s=2.0, robot_id="robot-sim")
    changes = []
    behaviour.listeners.append(changes.append)
    plans = generated_transports(
        seed=seed,
        locomotion=locomotion,
        count=count,
        duration_s=30.0,
        events=events,
        rates=None if events else RATES,
    )
    for number, plan in enumerate(plans):
        transport = f"t-{locomotion}-{number}"
        observations = list(plan.observations)
        pipeline.start_transport(
            transport, 1_000_000.0 + number * 100, plan.patient, None, plan.fps
        )
        first = len(changes)
        truths = []
        for observation in observations:
            pipeline.process(observation)
            truths.append(
                DEFAULT_TAXONOMY.decision(observation.truth, mode) if observation.truth else None
            )
        pipeline.end_transport(observations[-1].timestamp)
        yield transport, plan, truths, changes[first:], behaviour


@pytest.mark.parametrize(
    ("mode", "locomotion"),
    [(TransportMode.WALKING, "walking"), (TransportMode.WHEELCHAIR, "wheelchair")],
)
def test_every_generated_emergency_stops_the_robot_until_a_resolve_or_a_reset(
    tmp_path, mode, locomotion
):
    emergencies = 0
    for number, (transport, plan, truths, changes, behaviour) in enumerate(
        _run(tmp_path, mode, locomotion, seed=700)
    ):
        if Decision.EMERGENCY not in truths:
            assert BehaviourState.EMERGENCY_STOP not in {c.state for c in changes}, transport
            continue
        emergencies += 1
        stops = [c for c in changes if c.state == BehaviourState.EMERGENCY_STOP]
        assert stops, f"{transport} ({plan.generated_events}): an Emergency but no stop"
        # Once stopped it stays stopped to the end of the transport, whatever follows.
        assert changes[-1].state == BehaviourState.EMERGENCY_STOP, (transport, changes[-1])
        assert changes.index(stops[0]) == len(changes) - 1
        assert behaviour.state == BehaviourState.EMERGENCY_STOP
        # Released only from outside: a nurse's resolve, or (every other one) a local reset.
        if number % 2:
            released = behaviour.resolved(alarm_id=number + 1, by="nurse:nina")
            assert "resolved by nurse:nina" in released.reason
        else:
            released = behaviour.reset(who="cli")
            assert behaviour.resets[-1][3] == "cli"
        assert released.state == BehaviourState.TRANSPORTING
    assert emergencies >= 2, "the generated transports hold too few Emergencies to test"


@pytest.mark.parametrize("situation", PAUSE_EVENTS)
def test_every_pause_situation_in_wheelchair_mode_pauses_and_resumes(tmp_path, situation):
    pauses = 0
    for transport, plan, truths, changes, behaviour in _run(
        tmp_path, TransportMode.WHEELCHAIR, "wheelchair", seed=900, events=[situation], count=2
    ):
        if behaviour.state == BehaviourState.EMERGENCY_STOP:
            behaviour.reset(who="test")
        # Each run of Pause frames (a Pause situation) until the first Emergency.
        until = truths.index(Decision.EMERGENCY) if Decision.EMERGENCY in truths else len(truths)
        runs, inside = 0, False
        for decision in truths[:until]:
            if decision == Decision.PAUSE and not inside:
                runs += 1
            inside = decision == Decision.PAUSE
        if not runs:
            continue
        pauses += runs
        states = [c.state for c in changes]
        paused = states.count(BehaviourState.PAUSED)
        assert paused >= 1, f"{transport} ({plan.generated_events}): Pause but never paused"
        resumed = [
            b
            for a, b in zip(states, states[1:], strict=False)
            if a == BehaviourState.PAUSED and b == BehaviourState.TRANSPORTING
        ]
        # Every pause is followed by a resume, unless an Emergency stopped it or the transport
        # ended inside the hold time.
        ended_paused = states[-1] == BehaviourState.PAUSED
        stopped = BehaviourState.EMERGENCY_STOP in states
        assert len(resumed) + ended_paused + stopped >= paused, (transport, states)
        assert len(resumed) >= 1 or stopped or ended_paused, (transport, states)
    assert pauses >= 2, f"the generated {situation} transports hold too few Pause frames"
