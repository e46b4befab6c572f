"""Which model a robot starts with, and what it keeps of an assignment across a restart."""

from __future__ import annotations

import pytest

from robot_agent.config import ConfigError, load_settings
from robot_agent.models import last_running, remember_running
from robot_agent.runner import starting_classifier

from .tiny_model import write_upright_model


def test_the_last_assigned_model_is_started_after_a_restart(tmp_path):
    models = tmp_path / "robot-models"
    shipped = write_upright_model(tmp_path / "shipped", "upright-1")
    write_upright_model(models / "robot-a" / "upright-7", "upright-7")
    settings = load_settings(
        None, robot_id="robot-a", model_dir=str(shipped), models_dir=str(models)
    )
    assert starting_classifier(settings, "robot-a").manifest.version == "upright-1"
    remember_running(models / "robot-a", "upright-7")
    assert starting_classifier(settings, "robot-a").manifest.version == "upright-7"


def test_a_remembered_model_damaged_on_disk_is_not_started(tmp_path):
    robot_models = tmp_path / "robot-models" / "robot-a"
    stored = write_upright_model(robot_models / "upright-7", "upright-7")
    remember_running(robot_models, "upright-7")
    (stored / "model.onnx").write_bytes((stored / "model.onnx").read_bytes() + b"x")
    classifier, refusal = last_running(robot_models)
    assert classifier is None
    assert refusal.version == "upright-7" and "sha256 mismatch" in refusal.reason


def test_a_tampered_shipped_model_is_a_configuration_error(tmp_path):
    shipped = write_upright_model(tmp_path / "shipped", "upright-1")
    (shipped / "model.onnx").write_bytes(b"not the model")
    settings = load_settings(None, robot_id="robot-a", model_dir=str(shipped))
    with pytest.raises(ConfigError, match="model_dir: refused, .*sha256 mismatch"):
        starting_classifier(settings, "robot-a")
