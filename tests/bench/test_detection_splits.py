import math

from bench.detection_splits import _per_sequence, markdown_tables


def _event(sequence, kind, false_alarm=False, time_to_alarm_s=None):
    return {
        "sequence": sequence,
        "kind": kind,
        "false_alarm": false_alarm,
        "time_to_alarm_s": time_to_alarm_s,
    }


def _split(seed: int, fall_01_time_s: float) -> dict:
    """adl-02 alarms and fall-02 is missed on every split; fall-01's time to alarm varies."""
    return {
        "seed": seed,
        "events": [
            _event("adl-01", "adl", False),
            _event("adl-02", "adl", True),
            _event("fall-01", "fall", time_to_alarm_s=fall_01_time_s),
            _event("fall-02", "fall", time_to_alarm_s=None),
        ],
    }


SPLITS = [_split(0, 0.3), _split(1, 0.7)]


def test_per_sequence_counts_alarming_splits_and_keeps_every_fall_time():
    result = _per_sequence(SPLITS)
    assert result["adl_false_alarm_splits"] == {"adl-02": 2}
    assert result["fall_time_to_alarm_s"] == {"fall-01": [0.3, 0.7], "fall-02": [None, None]}


def test_tables_name_alarming_activities_and_slow_or_missed_falls():
    point = {
        "threshold": 0.5,
        "delay_ms": 200,
        "falls_detected": 1,
        "falls_total": 2,
        "adl_false_alarms": 1,
        "adl_total": 2,
        "median_time_to_alarm_s": 0.5,
        "frame_recall": 0.8,
        "frame_f1": 0.8,
    }
    splits = [
        {
            **split,
            "frame_recall": 0.8,
            "frame_f1": 0.8,
            "falls_detected": 1,
            "falls_total": 2,
            "adl_false_alarms": 1,
            "adl_total": 2,
            "median_time_to_alarm_s": 0.5,
            "fold_operating_points": [{"threshold": 0.5, "delay_ms": 200}],
        }
        for split in SPLITS
    ]
    result = {
        "splits": splits,
        "per_sequence": _per_sequence(SPLITS),
        "operating_curve": {
            "pooled_splits": 2,
            "falls_total": 4,
            "adl_total": 4,
            "points": [point],
        },
    }
    text = markdown_tables(result)
    assert "adl-02 (2)" in text and "adl-01" not in text
    # fall-01's median (0.5 s) is not above 0.5 s; fall-02 was missed in both splits.
    assert f"fall-02 ({math.inf:.2f})" in text and "fall-01" not in text


def test_the_split_study_runs_the_model_bench_detection_found_best(tmp_path):
    from bench.detection_splits import best_model

    results = tmp_path / "detection_urfd.json"
    assert best_model(results) == "gbt"  # bench-detection has not run
    results.write_text('{"best": "rf"}')
    assert best_model(results) == "rf"
