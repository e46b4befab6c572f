import numpy as np
import pytest

from vigil.formats import from_coco17, from_mediapipe33, from_movenet13, from_openpose_json
from vigil.skeleton import INDEX


def test_openpose_json_people_become_frames():
    flat = np.zeros((25, 3), np.float32)
    flat[INDEX["nose"]] = (100, 50, 0.9)
    flat[INDEX["l_ankle"]] = (120, 400, 0.7)
    flat[INDEX["r_ankle"]] = (5, 5, 0.0)  # missing: coordinates must not survive
    doc = {
        "version": 1.3,
        "people": [
            {"pose_keypoints_2d": flat.ravel().tolist()},
            {"pose_keypoints_2d": (flat * 2).ravel().tolist()},
        ],
    }
    frames = from_openpose_json(doc, timestamp=1.5)
    assert len(frames) == 2
    assert frames[0].timestamp == 1.5
    np.testing.assert_allclose(frames[0].keypoints[INDEX["nose"]], (100, 50, 0.9), rtol=1e-6)
    assert frames[0].keypoints[INDEX["r_ankle"]].tolist() == [0, 0, 0]
    assert np.isnan(frames[0].depth).all()


def test_openpose_json_bad_length_names_the_field():
    with pytest.raises(ValueError, match=r"people\[0\].pose_keypoints_2d"):
        from_openpose_json({"people": [{"pose_keypoints_2d": [1, 2, 3]}]})


def test_coco17_maps_names_and_derives_neck_and_mid_hip():
    coco = np.zeros((17, 3), np.float32)
    coco[0] = (10, 20, 0.9)  # nose
    coco[5] = (30, 40, 0.8)  # l_shoulder
    coco[6] = (10, 40, 0.6)  # r_shoulder
    coco[11] = (28, 80, 0.9)  # l_hip
    coco[12] = (12, 80, 0.5)  # r_hip
    coco[16] = (11, 120, 0.0)  # r_ankle missing
    frame = from_coco17(coco)
    kp = frame.keypoints
    np.testing.assert_allclose(kp[INDEX["nose"]], (10, 20, 0.9), rtol=1e-6)
    np.testing.assert_allclose(kp[INDEX["l_shoulder"]], (30, 40, 0.8), rtol=1e-6)
    np.testing.assert_allclose(kp[INDEX["neck"]], (20, 40, 0.6), rtol=1e-6)
    np.testing.assert_allclose(kp[INDEX["mid_hip"]], (20, 80, 0.5), rtol=1e-6)
    assert kp[INDEX["r_ankle"]].tolist() == [0, 0, 0]
    assert kp[INDEX["l_big_toe"], 2] == 0  # COCO has no feet


def test_movenet13_zero_means_missing_and_scales_to_pixels():
    pts = np.zeros((13, 2), np.float32)
    pts[0] = (0.5, 0.25)  # nose
    pts[12] = (0.25, 0.75)  # r_ankle
    frame = from_movenet13(pts, image_size=(640, 480))
    kp = frame.keypoints
    np.testing.assert_allclose(kp[INDEX["nose"]], (320, 120, 1.0))
    np.testing.assert_allclose(kp[INDEX["r_ankle"]], (160, 360, 1.0))
    assert kp[INDEX["l_shoulder"], 2] == 0
    assert kp[INDEX["neck"], 2] == 0  # shoulders missing: no derived neck


def test_mediapipe33_visibility_is_confidence():
    lm = np.zeros((33, 4), np.float32)
    lm[0] = (0.5, 0.5, -0.3, 0.95)
    lm[31] = (0.2, 0.9, 0.1, 0.4)  # left foot index -> l_big_toe
    lm[17] = (0.3, 0.3, 0.0, 0.9)  # pinky: no BODY_25 slot
    kp = from_mediapipe33(lm, image_size=(100, 200)).keypoints
    np.testing.assert_allclose(kp[INDEX["nose"]], (50, 100, 0.95), rtol=1e-6)
    np.testing.assert_allclose(kp[INDEX["l_big_toe"]], (20, 180, 0.4), rtol=1e-6)
    assert (kp[:, 2] > 0).sum() == 2


def test_wrong_shapes_are_refused():
    with pytest.raises(ValueError, match="coco17"):
        from_coco17(np.zeros((13, 3)))
    with pytest.raises(ValueError, match="mediapipe33"):
        from_mediapipe33(np.zeros((33, 3)))
