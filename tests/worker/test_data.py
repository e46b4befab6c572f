import numpy as np
import pytest

from vigil.classes import TransportMode
from worker.training.data import FrameData, with_emergency_lead

NORMAL, EMERGENCY, UNLABELLED = 0, 1, -1


def _frames(target: list[int], fps: float = 10.0) -> FrameData:
    n = len(target)
    return FrameData(
        names=["fall-x"],
        is_positive_sequence=np.array([True]),
        features=np.zeros((n, 1), np.float32),
        target=np.array(target),
        group=np.zeros(n, int),
        timestamps=np.arange(n) / fps,
        usable=np.ones(n, bool),
        mode=TransportMode.WALKING,
        data_sha256="crafted",
    )


def test_emergency_lead_fits_the_normal_frames_before_each_emergency_run_as_emergency():
    target = [NORMAL] * 6 + [UNLABELLED] + [NORMAL] * 3 + [EMERGENCY] * 3 + [NORMAL] * 3
    target += [EMERGENCY] * 2
    data = with_emergency_lead(_frames(target), 0.3)
    expected = list(target)
    expected[7:10] = [EMERGENCY] * 3  # 0.3 s before the run starting at frame 10
    expected[13:16] = [EMERGENCY] * 3  # and before the run starting at frame 16
    assert data.fit_target.tolist() == expected
    assert data.target.tolist() == target  # thresholds, delays and evaluation are unchanged


def test_emergency_lead_keeps_unlabelled_frames_out_of_training():
    target = [NORMAL] * 4 + [UNLABELLED] + [EMERGENCY] * 2
    data = with_emergency_lead(_frames(target), 0.2)
    assert data.fit_target.tolist() == [NORMAL] * 3 + [EMERGENCY, UNLABELLED] + [EMERGENCY] * 2


def test_no_lead_fits_the_labelled_targets():
    target = [NORMAL] * 4 + [EMERGENCY] * 2
    assert _frames(target).fit_target.tolist() == target
    assert with_emergency_lead(_frames(target), 0.0).fit_target.tolist() == target


def test_negative_lead_is_refused():
    with pytest.raises(ValueError, match="emergency lead"):
        with_emergency_lead(_frames([NORMAL, EMERGENCY]), -0.1)
