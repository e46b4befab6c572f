"""vigil-robot: bad configuration exits with a message naming the field."""

import json
import subprocess
import sys

import pytest

from robot_agent.cli import main


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--backend-url", "http://host/ws/robot", "--token", "t"], "backend_url"),
        (["--mode", "bicycle", "--token", "t"], "mode"),
        (["--speed", "fast", "--token", "t"], "speed"),
        (["--source", "webcam", "--token", "t"], "source"),
        (["--ground-truth"], "token"),
        (["--token", "t"], "model_dir"),
    ],
)
def test_bad_flag_names_the_field(args, field, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "bad configuration" in err and field in err


def test_config_file_values_are_checked_too(tmp_path, capsys):
    config = tmp_path / "robot.toml"
    config.write_text('[robot]\nrobot_id = "r-1"\ntoken = "t"\noutbox_max_frames = 3\n')
    assert main(["--config", str(config), "--ground-truth"]) == 2
    assert "outbox_max_frames" in capsys.readouterr().err
    assert main(["--config", str(tmp_path / "missing.toml")]) == 2
    assert "missing.toml" in capsys.readouterr().err


def test_console_script_module_runs_and_reports_unreachable_backend_then_stops(tmp_path):
    """A real run: the simulator streams GENERATED ground truth; no backend is listening, so
    frames stay in the outbox; SIGTERM-free stop via --transports 1 at high speed."""
    tokens = tmp_path / "tokens.json"
    tokens.write_text(json.dumps({"robot-1": "x"}))
    result = subprocess.run(
        [sys.executable, "-m", "robot_agent.cli", "--token", "x", "--ground-truth",
         "--backend-url", "ws://127.0.0.1:9/ws/robot", "--transports", "1",
         "--speed", "50", "--drain-timeout-s", "1",
         "--outbox-path", str(tmp_path / "o.sqlite")],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "backend unreachable" in result.stderr
    assert "still unacknowledged" in result.stderr
    from robot_agent.outbox import Outbox

    assert len(Outbox(tmp_path / "o.sqlite")) > 100
