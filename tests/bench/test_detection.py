"""bench.detection's per-model table and the lost-while-falling rule's own figures (issue #34)."""

from bench.detection import lost_while_falling_figures, markdown_table
from vigil.datasets import urfd


def test_rule_is_benchmarked_like_a_model_on_real_urfd():
    """REAL URFD, every recording: the rule alone adds no daily-activity alarm and fires on the
    falls where the pose estimator loses a patient going down fast (at most 1.2 s after the
    first Emergency-labelled frame)."""
    figures = lost_while_falling_figures(urfd.load())
    assert figures["falls_total"] == 30 and figures["adl_total"] == 40
    assert figures["adl_false_alarms"] == 0 and figures["adl_fired"] == []
    assert figures["falls_detected"] == len(figures["falls_fired"]) >= 5
    assert figures["max_time_to_alarm_s"] <= 1.2


def test_table_reports_refused_frames_apart_from_dropped_ones():
    path = {
        "frame_recall": 0.9,
        "frame_f1": 0.9,
        "falls_detected": 30,
        "falls_total": 30,
        "adl_false_alarms": 0,
        "adl_total": 40,
        "median_time_to_alarm_s": 0.5,
        "tracker_dropped_frames": 0,
        "tracker_refused_implausible_frames": 40,
    }
    model = {
        "name": "gbt",
        "inputs": ["keypoints"],
        "robot_path": path,
        **{k: v for k, v in path.items() if not k.startswith("tracker")},
        "threshold": 0.4,
        "delay_ms": 340,
    }
    table = markdown_table({"models": [model], "best": "gbt"})
    assert "| refused as implausible |" in table.splitlines()[0]
    assert "| 0 | 40 |" in table.splitlines()[2]
