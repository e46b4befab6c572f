import numpy as np

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
