"""Two backend replicas on one database: the robot agent is given both; when the replica it
streams to (and that runs the alarm monitor) is killed with -9, the robot streams to the other
within seconds, the other takes over the duties, no acknowledged frame is lost and the fall is
alarmed exactly once."""

from __future__ import annotations

import time

from .conftest import wait_for
from .test_live_streaming import emergency_alarms, frames_by_seq
from .tiny_model import write_upright_model


def test_a_replica_killed_mid_transport_hands_its_robot_and_duties_to_the_other(
    backend, agents, tmp_path
):
    other = backend.replica("replica-2")
    other.start()
    try:
        assert backend.duties()["leading"] and not other.duties()["leading"]
        model = write_upright_model(tmp_path / "model", "upright-1", threshold=0.5, delay_ms=200)
        agent = agents(
            backend,
            *["--source", "generated", "--scenario", "fall", "--seed", "3", "--people", "1"],
            *["--duration-s", "12", "--speed", "2", "--model-dir", str(model)],
            "--exit-when-done",
            backend_url=f"{backend.robot_ws_url},{other.robot_ws_url}",
        )
        wait_for(lambda: frames_by_seq(backend)[0] >= 60, 60, "the first frames to be stored")
        assert emergency_alarms(backend) == []  # still walking
        stored_before = frames_by_seq(backend)[0]
        backend.kill()
        killed_at = time.monotonic()

        wait_for(lambda: frames_by_seq(other)[0] > stored_before + 10, 10, "frames via replica-2")
        streaming_again_s = time.monotonic() - killed_at
        assert streaming_again_s < 5, f"streaming again after {streaming_again_s:.1f} s"
        wait_for(lambda: other.duties()["leading"], 5, "replica-2 to take over the duties")
        assert "connected to " + other.robot_ws_url in agent.log()

        assert agent.process.wait(60) == 0, agent.log()[-3000:]
        sent = agent.next_seq()
        count, distinct, first, last = frames_by_seq(other)
        assert (count, distinct, first, last) == (sent, sent, 0, sent - 1)
        wait_for(lambda: emergency_alarms(other), 10, "the fall's Emergency")
        assert len(emergency_alarms(other)) == 1
    finally:
        other.stop()
