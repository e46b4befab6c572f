"""bench/demo_hour.py reads the simulated fleet's ground truth from its log: each GENERATED
transport's events, as robot_agent.agent logs them when the transport starts."""

from __future__ import annotations

from bench.demo_hour import generated_falls
from robot_agent.agent import TransportPlan, transport_started


def test_falls_are_counted_per_robot_from_the_agents_transport_lines():
    lines = ["==> starting backend", "15:46:18 INFO    transport robot-2-17-1 ended: 901 frames"]
    for number, (robot, events) in enumerate((
        ("robot-1", ("stumbling",)), ("robot-1", ("turning",)), ("robot-2", ("fall",)),
        ("robot-3", ()),
    )):  # fmt: skip
        plan = TransportPlan([], patient=None, location="corridor (GENERATED data)",
                             generated_events=events)  # fmt: skip
        lines.append(f"15:47:36 INFO    {transport_started(robot, f'{robot}-17-{number}', plan)}")
    counted = generated_falls("\n".join(lines))
    assert counted["transports"] == {"robot-1": 2, "robot-2": 1, "robot-3": 1}
    assert counted["falls"] == {"robot-1": 1, "robot-2": 1}
    assert counted["falls_total"] == 2
    assert counted["events"] == {"stumbling": 1, "turning": 1, "fall": 1}
