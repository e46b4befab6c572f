"""Frames without a usable pose hold the last usable frame's scores for up to HOLD_S seconds
(vigil.runtime), streamed and in bulk alike. The model here is hand-made (GENERATED frames): it
scores Emergency for a lying torso and Normal on any held frame, so only the hold keeps an
Emergency across a pose estimator's dropout."""

from __future__ import annotations

import numpy as np
from onnx import TensorProto, helper

from vigil.classes import Decision, TransportMode
from vigil.features import FEATURE_NAMES, FEATURE_SETS, FEATURE_VERSION, extract_sequence
from vigil.model_file import ModelManifest, load_classifier, write_model
from vigil.policy import apply_delay, raw_decisions
from vigil.runtime import HELD, HOLD_S, FrameClassifier, hold_scores
from vigil.skeleton import SkeletonFrame, empty_keypoints
from vigil.taxonomy import DEFAULT_TAXONOMY

FPS = 30.0


def _held_normal_model(directory, delay_ms: int = 200):
    columns = list(FEATURE_SETS["pose"])
    weights = np.zeros((len(columns), 2), np.float32)
    weights[columns.index(FEATURE_NAMES.index("upright"))] = (6.0, -6.0)
    weights[columns.index(HELD)] = (20.0, -20.0)  # a held frame: Normal, whatever the pose
    bias = np.array([-3.0, 3.0], np.float32)
    graph = helper.make_graph(
        [
            helper.make_node("MatMul", ["features", "w"], ["product"]),
            helper.make_node("Add", ["product", "b"], ["logits"]),
            helper.make_node("Softmax", ["logits"], ["probabilities"], axis=1),
        ],
        "held-normal",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, [None, len(columns)])],
        [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, [None, 2])],
        [
            helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel()),
            helper.make_tensor("b", TensorProto.FLOAT, bias.shape, bias),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    manifest = ModelManifest(
        version="held-normal-1", name="held-normal", mode=TransportMode.WALKING,
        classes=[Decision.NORMAL, Decision.EMERGENCY], feature_version=FEATURE_VERSION,
        feature_set="pose", taxonomy_version=DEFAULT_TAXONOMY.version, threshold=0.5,
        delay_ms=delay_ms, training_data_sha256="0" * 64, generated_data=True, sha256="0" * 64,
    )  # fmt: skip
    return write_model(directory, model.SerializeToString(), manifest)


def _lying(t: float) -> SkeletonFrame:
    keypoints = np.zeros((25, 3), np.float32)
    keypoints[:, 0] = np.linspace(100, 400, 25)  # head to feet along the floor
    keypoints[:, 1] = 300 + 5 * np.sin(np.arange(25))
    keypoints[:, 2] = 1.0
    return SkeletonFrame(keypoints, timestamp=t)


def _stream(pattern: str) -> list[SkeletonFrame]:
    """'L': the patient lying, '.': no pose (the pose estimator lost them)."""
    return [
        _lying(i / FPS) if c == "L" else SkeletonFrame(empty_keypoints(), timestamp=i / FPS)
        for i, c in enumerate(pattern)
    ]


def test_a_short_dropout_mid_fall_does_not_restart_the_delay(tmp_path):
    runtime = FrameClassifier.from_dir(_held_normal_model(tmp_path / "m", delay_ms=200))
    frames = _stream("LLLL...LLLLLLLL")
    out = [runtime.classify(f) for f in frames]
    emergency = [c.scores[Decision.EMERGENCY] for c in out]
    assert min(emergency) > 0.9  # held through frames 4-6
    decisions = [c.decision for c in out]
    # Raw Emergency from frame 0; 200 ms later (frame 6, inside the dropout) the alarm.
    assert decisions.index(Decision.EMERGENCY) == 6


def test_the_hold_ends_after_hold_s_and_bulk_equals_streamed(tmp_path):
    model_dir = _held_normal_model(tmp_path / "m")
    runtime = FrameClassifier.from_dir(model_dir)
    gap = int(HOLD_S * FPS) + 10
    frames = _stream("LLLLLL" + "." * gap + "LL")
    streamed = np.array([runtime.scores(f) for f in frames])
    times = np.array([f.timestamp for f in frames])
    last_usable = 5
    within = times - times[last_usable] <= HOLD_S + 1e-9
    assert (streamed[6:][within[6:]] == streamed[last_usable]).all()
    assert (streamed[6 : 6 + gap][~within[6 : 6 + gap], 1] < 0.01).all()  # the model's own
    assert streamed[-1, 1] > 0.9
    # Bulk: features of the whole stream, the model on all rows, then hold_scores.
    features = extract_sequence(frames, "pose")
    classifier = load_classifier(model_dir)
    held = features[:, list(FEATURE_SETS["pose"]).index(HELD)] > 0
    bulk = hold_scores(classifier.predict_proba(features), held, times)
    np.testing.assert_allclose(bulk, streamed, atol=1e-6)
    normal = 0
    bulk_decisions = apply_delay(raw_decisions(bulk, classifier.manifest.classes, 0.5), times,
                                 0.2, normal)  # fmt: skip
    runtime.reset()
    stream_decisions = [runtime.classify(f).decision for f in frames]
    classes = classifier.manifest.classes
    assert [classes[i] for i in bulk_decisions] == stream_decisions


def test_no_usable_pose_yet_means_the_models_own_scores():
    scores = np.array([[0.2, 0.8], [0.9, 0.1], [0.3, 0.7]])
    held = np.array([True, False, True])
    out = hold_scores(scores, held, np.array([0.0, 0.1, 0.2]))
    np.testing.assert_array_equal(out, [[0.2, 0.8], [0.9, 0.1], [0.9, 0.1]])
