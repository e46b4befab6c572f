import json

import pytest

from tests.robot_agent.tiny_model import write_upright_model
from vigil.features import FEATURE_VERSION
from vigil.model_file import ModelManifest, write_model
from vigil.runtime import FrameClassifier


def test_runtime_refuses_a_model_built_for_other_features(tmp_path):
    model_dir = tmp_path / "ok"
    write_upright_model(model_dir, "1")
    FrameClassifier.from_dir(model_dir)  # same feature version: accepted
    manifest = ModelManifest.model_validate_json((model_dir / "manifest.json").read_text())
    old = manifest.model_copy(update={"feature_version": FEATURE_VERSION - 1})
    stale = tmp_path / "stale"
    write_model(stale, (model_dir / "model.onnx").read_bytes(), old)
    expected = f"feature version {FEATURE_VERSION - 1}.*computes {FEATURE_VERSION}"
    with pytest.raises(ValueError, match=expected):
        FrameClassifier.from_dir(stale)
    stored = json.loads((stale / "manifest.json").read_text())
    assert stored["feature_version"] == FEATURE_VERSION - 1
