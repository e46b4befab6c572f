"""bench/demo_lookalikes.py plays GENERATED transports, as the simulated fleet makes them,
through the robot's own frame path and says which ones alarmed."""

from __future__ import annotations

from bench.demo_lookalikes import play
from tests.robot_agent.tiny_model import write_upright_model


def test_the_model_decides_each_transport_through_the_robot_pipeline(tmp_path):
    """A toy model (Emergency when the torso is less than half upright) alarms on a generated
    fall; one that never alarms does not, and the ground truth is reported either way."""
    model = write_upright_model(tmp_path / "m", "upright-1", delay_ms=200)
    quiet = write_upright_model(tmp_path / "q", "never-1", always_normal=True)
    fall = play(model, None, "fall", "walking", 70_000, tmp_path)
    standing = play(quiet, None, "standing", "walking", 70_000, tmp_path)
    missed = play(quiet, None, "fall", "walking", 70_000, tmp_path)
    assert not missed["alarmed"] and missed["truth_emergency_s"] == fall["truth_emergency_s"]
    assert fall["frames"] >= 900 and standing["frames"] >= 900  # 30 s or more, 30 frames/s
    assert fall["alarmed"] and fall["truth_emergency_s"] is not None
    assert fall["first_emergency_s"] >= fall["truth_emergency_s"] - 1.0
    assert not standing["alarmed"] and standing["truth_emergency_s"] is None
