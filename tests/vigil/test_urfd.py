import numpy as np
import pytest

from vigil.datasets import urfd


def test_label_mapping_follows_the_readme():
    fall, adl = urfd.load(names=["fall-01", "adl-40"])
    labelled = ~np.isnan(fall.urfd_label)
    assert np.all(fall.target[labelled & (fall.urfd_label == -1)] == urfd.NORMAL)
    assert np.all(fall.target[labelled & (fall.urfd_label >= 0)] == urfd.EMERGENCY)
    assert np.all(adl.target[~np.isnan(adl.urfd_label)] == urfd.NORMAL)  # lying on purpose too
    assert (adl.urfd_label == 1).any()
    assert np.all(adl.target[np.isnan(adl.urfd_label)] == urfd.UNLABELLED)
    assert np.all(fall.keypoints[~fall.detected] == 0)
    np.testing.assert_allclose(np.diff(fall.timestamps), 1 / 30)
    assert fall.first_emergency_time() is not None and adl.first_emergency_time() is None


def test_all_sequences_load():
    sequences = urfd.load()
    assert len(sequences) == 70
    assert sum(s.is_fall for s in sequences) == 30
    assert sum(len(s) for s in sequences) == 11_916


def test_floor_measures_come_from_the_official_depth_features():
    fall, adl = urfd.load(names=["fall-01", "adl-40"])
    assert fall.floor.shape == (len(fall), 3)
    # Official row for fall-01 frame 1: H 1899.5366 mm, D 1055.9988 mm, P40 0.04731.
    first = np.flatnonzero(fall.timestamps == 0)[0]
    assert fall.floor[first] == pytest.approx([1.8995366, 1.0559988, 0.04731], rel=1e-6)
    lying = fall.urfd_label == 1
    standing = fall.urfd_label == -1
    assert np.nanmedian(fall.floor[lying, 0]) < 0.8 < 1.4 < np.nanmedian(fall.floor[standing, 0])
    assert np.nanmedian(fall.floor[lying, 2]) > 0.5
    # Frames the official files do not list have no floor measures (NaN), never zeros.
    unlisted = np.isnan(adl.urfd_label)
    assert np.isnan(adl.floor[unlisted]).all() and np.isfinite(adl.floor[~unlisted]).all()
    frames = fall.frames()
    assert np.array_equal(frames[first].floor, fall.floor[first])
