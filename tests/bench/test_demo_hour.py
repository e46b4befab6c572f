"""bench/demo_hour.py reads the simulated fleet's ground truth from its log: each GENERATED
transport's events, as robot_agent.agent logs them when the transport starts."""

from __future__ import annotations

from bench.demo_hour import generated_falls
from robot_agent.agent import TransportPlan, transport_started


def test_falls_are_counted_per_robot_from_the_agents_transport_lines():
    lines = ["==> starting backend", "15:46:18 INFO    transport robot-2-17-1 ended: 901 frames"]
    for number, (robot, events) in enumerate(
        (
            ("robot-1", ("stumbling",)),
            ("robot-1", ("turning",)),
            ("robot-2", ("fall",)),
            ("robot-3", ()),
        )
    ):
        plan = TransportPlan(
            [], patient=None, location="corridor (GENERATED data)", generated_events=events
        )
        lines.append(f"15:47:36 INFO    {transport_started(robot, f'{robot}-17-{number}', plan)}")
    counted = generated_falls("\n".join(lines))
    assert counted["transports"] == {"robot-1": 2, "robot-2": 1, "robot-3": 1}
    assert counted["falls"] == {"robot-1": 1, "robot-2": 1}
    assert counted["falls_total"] == 2
    assert counted["events"] == {"stumbling": 1, "turning": 1, "fall": 1}


def test_alarms_are_matched_to_the_generated_falls_of_their_transport():
    from bench.demo_hour import alarms_against_falls

    lines = [
        transport_started(robot, transport, TransportPlan([], generated_events=events))
        for robot, transport, events in (
            ("robot-1", "t-fall", ("fall",)),
            ("robot-1", "t-stumble", ("stumbling",)),
            ("robot-2", "t-turn", ("turning",)),
            ("robot-2", "t-bed", ("lying_down_deliberately",)),
        )
    ]
    generated = generated_falls("\n".join(lines))
    alarms = [{"kind": "emergency", "transport_id": t} for t in ("t-fall", "t-turn", "t-bed")]
    alarms.append({"kind": "pause", "transport_id": "t-stumble"})  # not an Emergency
    assert alarms_against_falls(alarms, generated) == {
        "emergency_alarms": 3,
        "on_a_generated_fall": 1,
        "false_alarms": 2,
        "false_alarms_by_event": {"turning": 1, "lying_down_deliberately": 1},
        "falls_without_alarm": 1,
        "falls_without_alarm_events": {"stumbling": 1},
    }
