"""Configuration: file, environment and flags; bad values exit with code 2 naming the field."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from robot_agent.cli import main
from robot_agent.config import ConfigError, load_settings

REPO = Path(__file__).resolve().parents[2]


def test_file_then_environment_then_flags(tmp_path, monkeypatch):
    config = tmp_path / "robot.toml"
    config.write_text('robot_id = "r-file"\nheartbeat_s = 7\nspeed = 2.0\nmode = "wheelchair"\n')
    monkeypatch.setenv("VIGIL_ROBOT_HEARTBEAT_S", "3")
    settings = load_settings(config, speed="4")
    assert settings.robot_id == "r-file"  # file
    assert settings.heartbeat_s == 3.0  # environment beats file
    assert settings.speed == 4.0  # flag beats both
    assert settings.mode == "wheelchair"


@pytest.mark.parametrize(
    ("toml", "env", "flags", "field"),
    [
        ("outbox_budget_bytes = -1\n", {}, {}, "outbox_budget_bytes"),
        ("heartbeat_sec = 5\n", {}, {}, "heartbeat_sec: unknown setting"),
        ("", {"VIGIL_ROBOT_MODE": "flying"}, {}, "mode"),
        ("", {}, {"backend_url": "http://host/ws/robot"}, "backend_url: each URL must start"),
        ("", {}, {"backend_url": "ws://a/ws/robot, http://b"}, "backend_url: .*'http://b'"),
        ("", {}, {"backoff_initial_s": "9", "backoff_max_s": "1"}, "backoff_max_s"),
        ('camera_mount = "525,525,320,240"\n', {}, {}, "camera_mount: .*expected 6 numbers"),
        ("", {"VIGIL_ROBOT_CAMERA_MOUNT": "525,525,320,240,0,5"}, {}, "camera_mount: .*height_m"),
        ("", {}, {"camera_mount": "a,b,c,d,e,f"}, "camera_mount: .*expected numbers"),
    ],
)
def test_bad_values_name_the_field(tmp_path, monkeypatch, toml, env, flags, field):
    config = tmp_path / "robot.toml"
    config.write_text(toml)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    with pytest.raises(ConfigError, match=field):
        load_settings(config, **flags)


def test_several_backend_replicas_in_one_setting(tmp_path):
    config = tmp_path / "robot.toml"
    config.write_text(
        'backend_url = "ws://replica-1:8000/ws/robot, ws://replica-2:8000/ws/robot"\n'
    )
    settings = load_settings(config)
    assert settings.backend_urls == ["ws://replica-1:8000/ws/robot", "ws://replica-2:8000/ws/robot"]


def test_broken_toml_and_missing_file_are_named(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text("robot_id = \n")
    with pytest.raises(ConfigError, match="config: .*not valid TOML"):
        load_settings(broken)
    with pytest.raises(ConfigError, match="config: file .* not found"):
        load_settings(tmp_path / "missing.toml")


def test_token_from_a_plain_file_or_a_fleet_json(tmp_path):
    plain = tmp_path / "token"
    plain.write_text("secret-1\n")
    assert load_settings(None, robot_id="r", token_file=str(plain)).resolve_token() == "secret-1"
    fleet = tmp_path / "tokens.json"
    fleet.write_text(json.dumps({"r": "secret-2"}))
    assert load_settings(None, robot_id="r", token_file=str(fleet)).resolve_token() == "secret-2"
    with pytest.raises(ConfigError, match="token_file: .* no token for robot 'other'"):
        load_settings(None, robot_id="other", token_file=str(fleet)).resolve_token()


def test_cli_exits_2_with_a_message_naming_the_field(capsys, tmp_path):
    assert main(["run", "--robot-id", "r", "--token", "t", "--outbox-budget-bytes", "lots"]) == 2
    assert "outbox_budget_bytes" in capsys.readouterr().err
    assert main(["run", "--token", "t", "--outbox", str(tmp_path / "o.sqlite")]) == 2
    assert "robot_id: required" in capsys.readouterr().err
    bad_model = tmp_path / "no-model"
    assert main(["run", "--robot-id", "r", "--token", "t", "--model-dir", str(bad_model)]) == 2
    assert "model_dir" in capsys.readouterr().err
    assert main(["simulate", "--robots", "0", "--tokens-file", str(tmp_path / "x.json")]) == 2
    assert "robots: must be at least 1" in capsys.readouterr().err


def test_console_script_reports_bad_environment_value():
    result = subprocess.run(
        [sys.executable, "-m", "robot_agent.cli", "run", "--robot-id", "r", "--token", "t"],
        cwd=REPO,
        env={"PATH": "/usr/bin:/bin", "VIGIL_ROBOT_HEARTBEAT_S": "often"},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "bad configuration: heartbeat_s" in result.stderr


def test_a_camera_mount_is_read_into_its_geometry(tmp_path):
    config = tmp_path / "robot.toml"
    config.write_text('camera_mount = "570.3, 570.3, 319.5, 239.5, 1.1, 12"\n')
    mount = load_settings(config).mount
    assert (mount.fx, mount.cy, mount.height_m, mount.pitch_deg) == (570.3, 239.5, 1.1, 12.0)
    config.write_text("")
    assert load_settings(config).mount is None


def test_fallback_model_dir_must_be_keypoints_only(tmp_path):
    from robot_agent.runner import fallback_classifier

    from .tiny_model import write_upright_model

    floor = write_upright_model(tmp_path / "floor", "floor-1", feature_set="full")
    keypoints = write_upright_model(tmp_path / "kp", "kp-1", feature_set="keypoints")
    settings = load_settings(None, fallback_model_dir=str(floor))
    with pytest.raises(ConfigError, match="fallback_model_dir: model floor-1 needs keypoints, "):
        fallback_classifier(settings)
    settings = load_settings(None, fallback_model_dir=str(keypoints))
    assert fallback_classifier(settings).manifest.version == "kp-1"
    with pytest.raises(ConfigError, match="fallback_model_dir: .* not found"):
        fallback_classifier(load_settings(None, fallback_model_dir=str(tmp_path / "none")))
