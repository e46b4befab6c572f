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


def _keypoint_rows(sequence: str) -> tuple[list[str], list[list[str]]]:
    import csv
    import gzip

    with gzip.open(urfd.default_dir() / urfd.KEYPOINTS_FILE, "rt", newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        return header, [row for row in reader if row[0] == sequence]


def _write(path, header, rows):
    import csv
    import gzip

    with gzip.open(path, "wt", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def test_a_keypoint_file_in_urfds_format_loads_from_anywhere(tmp_path):
    header, rows = _keypoint_rows("fall-05")
    (sequence,) = urfd.load(
        names=["fall-05"], keypoints_file=_write(tmp_path / "k.csv.gz", header, rows)
    )
    (original,) = urfd.load(names=["fall-05"])
    np.testing.assert_array_equal(sequence.keypoints, original.keypoints)
    np.testing.assert_array_equal(sequence.target, original.target)
    assert np.isnan(sequence.floor).all()  # no label files beside it: floor measures unknown


def test_duplicated_frame_rows_are_refused_with_the_sequence_and_frame(tmp_path):
    header, rows = _keypoint_rows("fall-05")
    path = _write(tmp_path / "k.csv.gz", header, [*rows, rows[10]])
    frame = rows[10][header.index("npy_index")]
    with pytest.raises(ValueError, match=rf"fall-05 has more than one row for npy_index {frame}"):
        urfd.load(names=["fall-05"], keypoints_file=path)


def test_a_file_of_another_format_is_refused_naming_the_missing_columns(tmp_path):
    path = _write(tmp_path / "k.csv.gz", ["sequence", "frame"], [["fall-01", "1"]])
    with pytest.raises(ValueError, match="not in URFD's keypoint format, missing columns"):
        urfd.load(keypoints_file=path)


def test_observations_carry_the_person_where_detected_and_the_truth():
    (sequence,) = urfd.load(names=["fall-01"])
    observations = sequence.observations()
    assert [bool(o.people) for o in observations] == list(sequence.detected)
    truth = {o.truth for o in observations}
    assert {"walking", "falling", "lying_on_floor"} <= truth
