import json

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper

from vigil.classes import Decision, TransportMode
from vigil.model_file import (
    ModelIntegrityError,
    ModelManifest,
    load_classifier,
    read_manifest,
    write_model,
)


def _softmax_model(n_features: int) -> bytes:
    weights = np.zeros((n_features, 2), np.float32)
    weights[0] = (1.0, -1.0)
    graph = helper.make_graph(
        [
            helper.make_node("MatMul", ["features", "w"], ["logits"]),
            helper.make_node("Softmax", ["logits"], ["probabilities"], axis=1),
        ],
        "tiny",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, [None, n_features])],
        [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, [None, 2])],
        [helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel())],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    return model.SerializeToString()


def _manifest(**kw) -> ModelManifest:
    base = dict(
        version="t1",
        mode=TransportMode.WALKING,
        classes=[Decision.NORMAL, Decision.EMERGENCY],
        feature_version=1,
        taxonomy_version=1,
        threshold=0.5,
        delay_ms=100,
        training_data_sha256="ab" * 32,
        sha256="0" * 64,
    )
    return ModelManifest(**{**base, **kw})


def test_write_and_load_round_trip(tmp_path):
    write_model(tmp_path, _softmax_model(4), _manifest())
    classifier = load_classifier(tmp_path)
    p = classifier.predict_proba(np.array([[2.0, 0, 0, 0]], np.float32))
    np.testing.assert_allclose(p, [[1 / (1 + np.exp(-4)), 1 - 1 / (1 + np.exp(-4))]], rtol=1e-5)
    manifest, _ = read_manifest(tmp_path / "manifest.json")
    assert manifest.format == "onnx" and len(manifest.sha256) == 64


def test_tampered_model_is_refused_naming_both_hashes(tmp_path):
    write_model(tmp_path, _softmax_model(4), _manifest())
    manifest, _ = read_manifest(tmp_path)
    data = bytearray((tmp_path / "model.onnx").read_bytes())
    data[-1] ^= 0xFF
    (tmp_path / "model.onnx").write_bytes(bytes(data))
    with pytest.raises(ModelIntegrityError) as error:
        load_classifier(tmp_path)
    assert manifest.sha256 in str(error.value)
    assert error.value.actual != manifest.sha256 and error.value.actual in str(error.value)


def test_manifest_rejects_wrong_classes_and_paths():
    with pytest.raises(ValueError, match="classes"):
        _manifest(classes=[Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE])
    with pytest.raises(ValueError, match="file"):
        _manifest(file="../evil.onnx")
    assert onnx  # the graph helper above is real ONNX


# The manifest fields agents of the previous release know; they refuse any other top-level
# field (extra="forbid"), and a hospital's fleet upgrades robot by robot.
PREVIOUS_RELEASE_FIELDS = {
    "version",
    "created",
    "name",
    "mode",
    "classes",
    "feature_version",
    "feature_set",
    "window",
    "inputs",
    "taxonomy_version",
    "threshold",
    "delay_ms",
    "metrics",
    "training_data_sha256",
    "generated_data",
    "file",
    "sha256",
    "format",
}


def test_a_manifest_with_its_training_recordings_is_one_an_earlier_agent_reads(tmp_path):
    manifest = _manifest(metrics={"training_recordings": ["fall-02", "adl-01"]})
    write_model(tmp_path, _softmax_model(4), manifest)
    written = json.loads((tmp_path / "manifest.json").read_text())
    assert set(written) <= PREVIOUS_RELEASE_FIELDS
    assert read_manifest(tmp_path)[0].training_recordings == ["fall-02", "adl-01"]
    assert _manifest().training_recordings is None
