"""A patient lost while falling is an Emergency (issue #34): the rule beside the model
(vigil.policy.LostWhileFalling), in the frame path (vigil.detector), on crafted sequences and on
the REAL URFD recordings."""

from __future__ import annotations

import numpy as np
import pytest

from vigil.classes import Decision
from vigil.detector import Detector, patient_stream
from vigil.observation import Observation
from vigil.policy import LOST_FALL_SPEED, LOST_WHILE_FALLING, LostWhileFalling
from vigil.runtime import FrameClassifier
from vigil.skeleton import INDEX, N_KEYPOINTS, SkeletonFrame

FPS = 30.0
TORSO = 60.0  # pixels

#: A standing body around its hip centre, in torso lengths (x right, y down).
BODY = {
    "nose": (0.0, -1.3),
    "neck": (0.0, -1.0),
    "r_shoulder": (-0.35, -1.0),
    "l_shoulder": (0.35, -1.0),
    "r_elbow": (-0.45, -0.5),
    "l_elbow": (0.45, -0.5),
    "r_wrist": (-0.5, -0.05),
    "l_wrist": (0.5, -0.05),
    "mid_hip": (0.0, 0.0),
    "r_hip": (-0.2, 0.0),
    "l_hip": (0.2, 0.0),
    "r_knee": (-0.2, 0.85),
    "l_knee": (0.2, 0.85),
    "r_ankle": (-0.2, 1.7),
    "l_ankle": (0.2, 1.7),
}


def person(x: float, hip_y: float, t: float) -> SkeletonFrame:
    kp = np.zeros((N_KEYPOINTS, 3), np.float32)
    for name, (dx, dy) in BODY.items():
        kp[INDEX[name]] = (x + dx * TORSO, hip_y + dy * TORSO, 1.0)
    return SkeletonFrame(kp, timestamp=t)


def stream(
    hips_per_s: float, sideways_per_s: float = 0.0, moving_s: float = 0.5
) -> list[Observation]:
    """1 s standing, then ``moving_s`` of the hips going down at ``hips_per_s`` torso lengths per
    second (and sideways at ``sideways_per_s``), then 1 s with nobody found."""
    out, x, y = [], 320.0, 200.0
    n_still, n_moving = int(FPS), int(moving_s * FPS)
    for i in range(n_still + n_moving + int(FPS)):
        t = i / FPS
        if i < n_still + n_moving:
            if i >= n_still:
                y += hips_per_s * TORSO / FPS
                x += sideways_per_s * TORSO / FPS
            out.append(Observation(t, [person(x, y, t)], i))
        else:
            out.append(Observation(t, [], i))
    return out


LOST_AT = int(FPS) + int(0.5 * FPS)  # the first frame without the patient


def rule_over(observations: list[Observation]) -> np.ndarray:
    rule = LostWhileFalling()
    frames, seen = patient_stream(observations)
    return np.array([rule.update(f, s) for f, s in zip(frames, seen, strict=True)])


def test_fast_descent_then_lost_is_an_emergency_from_the_frame_lost():
    fired = rule_over(stream(hips_per_s=2 * LOST_FALL_SPEED))
    assert not fired[:LOST_AT].any()
    assert fired[LOST_AT:].all()  # at once, and while the patient stays lost


def test_slow_sit_down_then_lost_is_not():
    assert not rule_over(stream(hips_per_s=0.5 * LOST_FALL_SPEED)).any()


def test_walking_out_of_view_is_not():
    assert not rule_over(stream(hips_per_s=0.0, sideways_per_s=4.0)).any()


def test_seen_again_hands_back_to_the_model():
    observations = stream(hips_per_s=2 * LOST_FALL_SPEED)
    t = observations[-1].timestamp + 1 / FPS
    observations.append(Observation(t, [person(320, 300, t)], len(observations)))
    fired = rule_over(observations)
    assert fired[LOST_AT:-1].all() and not fired[-1]


def test_detector_decides_emergency_at_once_whatever_the_model_scores(tmp_path):
    from tests.robot_agent.tiny_model import write_upright_model

    model = write_upright_model(tmp_path / "m", "never-1", always_normal=True)
    detector = Detector(FrameClassifier.from_dir(model))
    results = [detector.process(o).classification for o in stream(2 * LOST_FALL_SPEED)]
    assert [c.decision for c in results[:LOST_AT]] == [Decision.NORMAL] * LOST_AT
    assert results[LOST_AT].decision is Decision.EMERGENCY
    assert results[LOST_AT].rule == LOST_WHILE_FALLING and not results[LOST_AT].pending
    # A slow sit-down the model calls Normal stays Normal.
    slow = [detector.process(o).classification for o in (detector.reset() or stream(0.5))]
    assert {c.decision for c in slow} == {Decision.NORMAL} and {c.rule for c in slow} == {None}


@pytest.fixture(scope="module")
def urfd_firing():
    from vigil.datasets import urfd

    fired = {}
    for sequence in urfd.load():
        rule = LostWhileFalling()
        frames, seen = patient_stream(sequence.observations())
        hits = [i for i, (f, s) in enumerate(zip(frames, seen, strict=True)) if rule.update(f, s)]
        fired[sequence.name] = hits
    return fired


def test_urfd_no_daily_activity_fires_and_falls_do(urfd_firing):
    """REAL URFD: the rule must add no false alarm on the 40 daily activities; the falls it
    fires on are reported (it fires where MoveNet loses a patient going down fast)."""
    adl = [n for n, hits in urfd_firing.items() if n.startswith("adl-") and hits]
    falls = sorted(n for n, hits in urfd_firing.items() if n.startswith("fall-") and hits)
    print(
        f"lost while falling fires on {len(falls)}/30 falls ({', '.join(falls)}), "
        f"{len(adl)}/40 daily activities"
    )
    assert adl == []
    assert len(falls) >= 5
