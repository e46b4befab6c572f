import numpy as np
import pytest

from vigil.datasets import urfd
from vigil.features import (
    FEATURE_NAMES,
    FEATURE_SETS,
    FLOOR_FEATURES,
    FeatureExtractor,
    extract_sequence,
    window_index,
)
from vigil.skeleton import INDEX, N_KEYPOINTS, SkeletonFrame


@pytest.fixture(scope="module")
def sequences():
    return urfd.load(names=["fall-19", "adl-21", "adl-40"])  # falls, dropouts, lying on purpose


def test_streaming_equals_batch_exactly_on_real_sequences(sequences):
    for seq in sequences:
        frames = seq.frames()
        for feature_set in FEATURE_SETS:
            batch = extract_sequence(frames, feature_set)
            extractor = FeatureExtractor(feature_set)
            streamed = np.stack([extractor.push(f) for f in frames])
            assert np.array_equal(batch, streamed), (seq.name, feature_set)
            assert np.isfinite(batch).all()
            assert batch.shape[1] == len(FEATURE_SETS[feature_set])


def test_floor_measures_enter_only_the_sets_that_declare_them(sequences):
    fall = sequences[0]
    frames = fall.frames()
    blind = [SkeletonFrame(f.keypoints, f.depth, f.timestamp) for f in frames]  # floor unknown
    names = np.array(FEATURE_NAMES)
    has_floor = list(FEATURE_NAMES).index("has_floor")
    with_floor, without = extract_sequence(frames), extract_sequence(blind)
    assert with_floor[:, has_floor].min() == 1.0 and without[:, has_floor].max() == 0.0
    floor_columns = np.array([n in FLOOR_FEATURES for n in names])
    # values + flag, drops, peaks, descent memory
    assert len(FLOOR_FEATURES) == 4 + 2 * 5 + 2 * 2 + 2
    assert "above_floor@0.4" in names[FEATURE_SETS["keypoints"]]  # made from keypoints
    assert not np.array_equal(with_floor[:, floor_columns], without[:, floor_columns])
    assert np.array_equal(with_floor[:, ~floor_columns], without[:, ~floor_columns])
    for feature_set in ("pose", "keypoints"):
        assert np.array_equal(
            extract_sequence(frames, feature_set), extract_sequence(blind, feature_set)
        )
    # The fall ends on the floor: the top drops by more than half a metre within 1.6 s somewhere.
    assert with_floor[:, list(FEATURE_NAMES).index("d_floor_top@1.6")].max() > 0.5


def test_streaming_equals_batch_with_irregular_timestamps_and_depth(sequences):
    rng = np.random.default_rng(1)
    seq = sequences[0]
    t = np.cumsum(rng.uniform(0.01, 0.2, len(seq)))
    depth = rng.uniform(1, 4, (len(seq), N_KEYPOINTS)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.3] = np.nan
    frames = [
        SkeletonFrame(k, d, float(ts)) for k, d, ts in zip(seq.keypoints, depth, t, strict=True)
    ]
    extractor = FeatureExtractor()
    streamed = np.stack([extractor.push(f) for f in frames])
    assert np.array_equal(extract_sequence(frames), streamed)
    assert streamed[:, FEATURE_NAMES.index("has_depth")].max() == 1.0


def test_missing_keypoints_are_not_zero_positions():
    kp = np.zeros((N_KEYPOINTS, 3), np.float32)
    kp[[0, 1, 2, 5, 8, 9, 12], :] = [
        [50, 10, 1],
        [50, 30, 1],
        [40, 30, 1],
        [60, 30, 1],
        [50, 80, 1],
        [45, 80, 1],
        [55, 80, 1],
    ]
    moved = kp.copy()
    moved[:, :2] += 1000  # translation of present keypoints only
    moved[kp[:, 2] == 0] = 0
    a = extract_sequence([SkeletonFrame(kp)])
    b = extract_sequence([SkeletonFrame(moved)])
    np.testing.assert_allclose(a, b, atol=1e-5)  # body-centred: the zeros did not leak in
    scaled = kp.copy()
    scaled[:, :2] *= 3
    np.testing.assert_allclose(a, extract_sequence([SkeletonFrame(scaled)]), atol=1e-5)


def test_frames_without_pose_hold_the_last_pose(sequences):
    seq = sequences[1]  # adl-21 has frames where nobody was detected
    features = extract_sequence(seq.frames())
    held = features[:, FEATURE_NAMES.index("held")] == 1
    assert held.any()
    first = np.flatnonzero(
        held & (np.arange(len(held)) > 0) & seq.detected[np.maximum(np.arange(len(held)) - 1, 0)]
    )[0]
    pose = slice(0, FEATURE_NAMES.index("held"))
    assert np.array_equal(features[first, pose], features[first - 1, pose])


def test_time_must_not_go_backwards():
    extractor = FeatureExtractor()
    extractor.push(SkeletonFrame(np.zeros((25, 3)), timestamp=1.0))
    with pytest.raises(ValueError, match="timestamps"):
        extractor.push(SkeletonFrame(np.zeros((25, 3)), timestamp=0.5))


def test_window_index_stays_inside_each_stream():
    index = window_index(np.array([0, 0, 0, 1, 1]), 3)
    assert index.tolist() == [[0, 0, 0], [0, 0, 1], [0, 1, 2], [3, 3, 3], [3, 3, 4]]


def test_non_finite_coordinates_count_as_missing():
    kp = np.zeros((N_KEYPOINTS, 3), np.float32)
    kp[[0, 1, 2, 5, 8, 9, 12], :] = [
        [50, 10, 1],
        [50, 30, 1],
        [40, 30, 1],
        [60, 30, 1],
        [50, 80, 1],
        [45, 80, 1],
        [55, 80, 1],
    ]
    broken = kp.copy()
    broken[3] = (np.nan, 5, 0.9)
    broken[4] = (np.inf, np.nan, 0.8)
    a, b = extract_sequence([SkeletonFrame(kp)]), extract_sequence([SkeletonFrame(broken)])
    assert np.isfinite(b).all()
    np.testing.assert_array_equal(a, b)


def test_stream_memory_counts_time_without_a_pose():
    standing = np.zeros((N_KEYPOINTS, 3), np.float32)
    standing[:, 0] = np.linspace(300, 340, N_KEYPOINTS)
    standing[:, 1] = np.linspace(100, 400, N_KEYPOINTS)
    standing[:, 2] = 0.9
    lying = standing.copy()
    lying[:, 0] = np.linspace(150, 450, N_KEYPOINTS)
    lying[:, 1] = np.linspace(380, 420, N_KEYPOINTS)
    lying[4:, 2] = 0.0  # most keypoints lost on the floor
    nobody = np.zeros_like(standing)
    poses = [standing] * 10 + [lying] * 5 + [nobody] * 9
    frames = [SkeletonFrame(k, timestamp=i / 30) for i, k in enumerate(poses)]
    features = extract_sequence(frames)
    since, missing, lost = (
        FEATURE_NAMES.index(n) for n in ("since_seen", "missing", "peak_d_visible@1.5")
    )
    assert features[9, since] == 0 and features[9, lost] == 0
    assert features[14, lost] > 0.5  # most keypoints vanished within 0.4 s
    assert features[-1, since] == pytest.approx(9 / 30, abs=1e-6)
    assert features[-1, missing] > features[15, missing] > 0 == features[14, missing]


def test_keypoints_set_does_not_depend_on_how_often_the_estimator_lost_the_person():
    """Feature version 6: how often one pose estimator loses a person is its habit (MoveNet in
    the training data, MediaPipe on a robot lose people in different frames), so the models for
    any camera (set `keypoints`) do not see it; the set `full` still does."""
    still = np.zeros((N_KEYPOINTS, 3), np.float32)
    still[:, 0] = np.linspace(300, 340, N_KEYPOINTS)
    still[:, 1] = np.linspace(100, 400, N_KEYPOINTS)
    still[:, 2] = 0.9
    nobody = np.zeros_like(still)
    always = [still] * 180  # 6 s of a person standing still
    dropped = [still] * 30 + [nobody] * 30 + [still] * 120  # lost for 1 s, then back
    features = {}
    for name, poses in (("always", always), ("dropped", dropped)):
        frames = [SkeletonFrame(k, timestamp=i / 30) for i, k in enumerate(poses)]
        features[name] = {s: extract_sequence(frames, s) for s in ("keypoints", "full")}
    # 3.5 s after the person is seen again: no change reaches back into the gap any more (3.2 s)
    back = 165
    assert np.array_equal(
        features["always"]["keypoints"][back], features["dropped"]["keypoints"][back]
    )
    assert not np.array_equal(features["always"]["full"][back], features["dropped"]["full"][back])
    names = set(np.array(FEATURE_NAMES)[FEATURE_SETS["keypoints"]])
    assert names.isdisjoint({"missing", "since_seen"}) and "held" in names


def _descent(tops: list[float], fps: float = 30.0) -> dict[str, np.ndarray]:
    """Features of a still skeleton whose top above the floor follows `tops` (metres, one per
    frame; NaN: floor unknown), by name."""
    kp = np.zeros((N_KEYPOINTS, 3), np.float32)
    kp[:, 0] = np.linspace(300, 340, N_KEYPOINTS)
    kp[:, 1] = np.linspace(100, 400, N_KEYPOINTS)
    kp[:, 2] = 0.9
    frames = [
        SkeletonFrame(kp, timestamp=i / fps, floor=np.array([top, top / 2, 0.1], np.float32))
        for i, top in enumerate(tops)
    ]
    features = extract_sequence(frames)
    return {name: features[:, i] for i, name in enumerate(FEATURE_NAMES)}


def test_descent_memory_holds_how_fast_the_person_went_down():
    fall = _descent([1.7] * 30 + list(np.linspace(1.7, 0.3, 15)) + [0.3] * 360)  # 1.4 m in 0.5 s
    slow = _descent([1.7] * 30 + list(np.linspace(1.7, 0.3, 120)) + [0.3] * 255)  # in 4 s
    descent, since = fall["floor_descent"], fall["floor_since_standing"]
    # Over 0.4 s (13 frames at 30 frames/s) the fall drops about 1.3 m, the slow one 0.15 m.
    assert descent[-1] == pytest.approx(1.4 * 13 / 14, abs=0.05)
    assert slow["floor_descent"][-1] == pytest.approx(1.4 * 13 / 119, abs=0.02)
    assert descent[29] == 0  # standing still: nothing yet
    # Held while the person stays down, long after the decaying peak has faded.
    assert descent[-1] == descent[60]
    peak = fall["peak_d_floor_top@4.0"]
    assert peak[-1] < 0.1 * peak.max()
    # Seconds since the top was last at standing height, capped.
    assert since[29] == 0
    assert since[-1] == pytest.approx(10.0)
    assert since[60] == pytest.approx(since[55] + 5 / 30, abs=1e-5)


def test_descent_memory_starts_over_when_the_top_is_back_at_standing_height():
    # A one-frame depth glitch while standing is gone with the next frame.
    descent = _descent([1.7] * 30 + [0.6] + [1.7] * 30)["floor_descent"]
    assert descent[30] > 1.0 and descent[31:].max() == 0
    # A fast drop, then standing up again: the memory starts over.
    features = _descent([1.7] * 30 + list(np.linspace(1.7, 0.4, 10)) + [0.4] * 30 + [1.7] * 30)
    descent, since = features["floor_descent"], features["floor_since_standing"]
    assert descent[69] > 1.0 and descent[-1] == 0 and since[-1] == 0
    # Floor unknown: the memory neither grows nor resets.
    tops = [1.7] * 30 + list(np.linspace(1.7, 0.4, 10)) + [float("nan")] * 20
    descent = _descent(tops)["floor_descent"]
    assert descent[-1] == descent[39] > 1.0


def _person(knee_xy, ankle_xy, shoulders_y=100.0) -> np.ndarray:
    """A front-facing person: shoulders, hips at y=200, knees and ankles where given (per side)."""
    kp = np.zeros((N_KEYPOINTS, 3), np.float32)
    for side, dx in (("r", -20.0), ("l", 20.0)):
        kp[INDEX[f"{side}_shoulder"]] = (300 + dx, shoulders_y, 0.9)
        kp[INDEX[f"{side}_hip"]] = (300 + dx, 200, 0.9)
        kp[INDEX[f"{side}_knee"]] = (300 + dx + knee_xy[0], knee_xy[1], 0.9)
        kp[INDEX[f"{side}_ankle"]] = (300 + dx + ankle_xy[0], ankle_xy[1], 0.9)
    kp[INDEX["neck"]] = (300, shoulders_y, 0.9)
    kp[INDEX["mid_hip"]] = (300, 200, 0.9)
    return kp


def _limb_features(kp) -> dict[str, float]:
    features = extract_sequence([SkeletonFrame(kp)])[0]
    return {name: float(features[FEATURE_NAMES.index(name)]) for name in FEATURE_NAMES}


def test_limb_geometry_tells_straight_legs_from_a_crouch():
    standing = _limb_features(_person(knee_xy=(0, 300), ankle_xy=(0, 400)))
    assert standing["knee_bend"] == pytest.approx(0, abs=1e-6)
    assert standing["hip_bend"] == pytest.approx(0, abs=1e-6)
    assert standing["thigh_down"] == pytest.approx(1) and standing["shank_down"] == pytest.approx(1)
    assert standing["lean"] == pytest.approx(1)
    # Crouching: thighs forward and horizontal, shanks back down, torso still upright.
    crouch = _limb_features(_person(knee_xy=(80, 200), ankle_xy=(80, 300)))
    assert crouch["knee_bend"] == pytest.approx(1, abs=1e-6)  # a right angle
    assert crouch["hip_bend"] == pytest.approx(1, abs=1e-6)
    assert crouch["thigh_down"] == pytest.approx(0, abs=1e-6)
    assert crouch["lean"] > 0.9
    # Tipped over with straight legs: the body far from upright over its feet.
    tipped = _person(knee_xy=(100, 230), ankle_xy=(200, 260), shoulders_y=170)
    tipped[[INDEX["r_shoulder"], INDEX["l_shoulder"], INDEX["neck"]], 0] -= 100
    fallen = _limb_features(tipped)
    assert fallen["knee_bend"] < 0.1 and fallen["lean"] < 0.5


def test_limb_geometry_without_its_keypoints_is_flagged_unknown():
    kp = _person(knee_xy=(80, 200), ankle_xy=(80, 300))
    kp[[INDEX["r_knee"], INDEX["l_knee"]], 2] = 0  # knees not found
    features = _limb_features(kp)
    for limb in ("knee_bend", "hip_bend", "thigh_down", "shank_down"):
        assert features[f"has_{limb}"] == 0 and features[limb] == 0
    assert features["has_lean"] == 1
    kp[INDEX["l_knee"], 2] = 0.8  # one side is enough
    assert _limb_features(kp)["has_knee_bend"] == 1


def test_limb_changes_cover_short_horizons_only():
    names = set(FEATURE_NAMES)
    assert {"d_knee_bend@0.2", "d_lean@0.8"} <= names
    assert "d_lean@1.6" not in names and "d_down@1.6" in names
    # a crouch within 0.4 s shows as knee bend gained over 0.4 s
    standing = _person(knee_xy=(0, 300), ankle_xy=(0, 400))
    crouch = _person(knee_xy=(80, 200), ankle_xy=(80, 300))
    frames = [SkeletonFrame(standing, timestamp=i / 30) for i in range(15)]
    frames += [SkeletonFrame(crouch, timestamp=(15 + i) / 30) for i in range(3)]
    features = extract_sequence(frames)
    assert features[-1, FEATURE_NAMES.index("d_knee_bend@0.4")] == pytest.approx(1, abs=1e-5)
    assert features[14, FEATURE_NAMES.index("d_knee_bend@0.4")] == 0
