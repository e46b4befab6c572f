"""A hand-made ONNX model for the agent's streaming tests: Emergency when the torso is less than
half upright (feature `upright`, pose feature set). It only drives the pipeline; it makes no
claim about detection quality (bench/robot.py times the real URFD-trained model)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from onnx import TensorProto, helper

from vigil.classes import Decision, TransportMode
from vigil.features import FEATURE_NAMES, FEATURE_SETS, FEATURE_VERSION
from vigil.model_file import ModelManifest, write_model
from vigil.taxonomy import DEFAULT_TAXONOMY


def upright_model_bytes(
    steepness: float = 6.0,
    feature_set: str = "pose",
    always_normal: bool = False,
    depth_weight: float = 0.0,
) -> bytes:
    """always_normal: ignore the features and score Normal 0.99 (a model that never alarms).
    depth_weight: added to the Emergency logit on frames with depth (`has_depth`), so that a
    test sees whether depth reached the model."""
    columns = list(FEATURE_SETS[feature_set])
    n_features = len(columns)
    weights = np.zeros((n_features, 2), np.float32)
    bias = np.array([-steepness / 2, steepness / 2], np.float32)
    if always_normal:
        bias = np.array([4.6, 0.0], np.float32)
    else:
        weights[columns.index(FEATURE_NAMES.index("upright"))] = (steepness, -steepness)
        weights[columns.index(FEATURE_NAMES.index("has_depth"))] = (0.0, depth_weight)
    graph = helper.make_graph(
        [
            helper.make_node("MatMul", ["features", "w"], ["product"]),
            helper.make_node("Add", ["product", "b"], ["logits"]),
            helper.make_node("Softmax", ["logits"], ["probabilities"], axis=1),
        ],
        "upright",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, [None, n_features])],
        [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, [None, 2])],
        [
            helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel()),
            helper.make_tensor("b", TensorProto.FLOAT, bias.shape, bias),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    return model.SerializeToString()


def write_upright_model(
    directory: Path,
    version: str,
    threshold: float = 0.5,
    delay_ms: int = 200,
    feature_set: str = "pose",
    always_normal: bool = False,
    depth_weight: float = 0.0,
) -> Path:
    manifest = ModelManifest(
        version=version,
        name="upright-test",
        mode=TransportMode.WALKING,
        classes=[Decision.NORMAL, Decision.EMERGENCY],
        feature_version=FEATURE_VERSION,
        feature_set=feature_set,
        taxonomy_version=DEFAULT_TAXONOMY.version,
        threshold=threshold,
        delay_ms=delay_ms,
        training_data_sha256="0" * 64,
        generated_data=True,
        sha256="0" * 64,
    )
    onnx = upright_model_bytes(
        feature_set=feature_set, always_normal=always_normal, depth_weight=depth_weight
    )
    return write_model(directory, onnx, manifest)
