"""`make run`'s supervisor on another data directory (VIGIL_VAR_DIR), as bench/demo_hour.py
runs it: every child's settings point there; settings given in the environment stay."""

from __future__ import annotations

import importlib
import os

import scripts.run_all as run_all


def test_var_dir_moves_everything_make_run_writes(tmp_path, monkeypatch):
    for name in ("VIGIL_DATABASE_URL", "VIGIL_SECRET_KEY_FILE", "VIGIL_MODEL_STORE_DIR",
                 "VIGIL_LABELLING_MODEL_DIR", "VIGIL_ARCHIVE_DIR",
                 "VIGIL_ROBOT_MODELS_DIR"):  # fmt: skip
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("VIGIL_VAR_DIR", str(tmp_path / "var"))
    monkeypatch.setenv("VIGIL_ARCHIVE_DIR", "/elsewhere/archive")  # given: kept
    module = importlib.reload(run_all)
    try:
        assert (tmp_path / "var").resolve() == module.VAR
        assert module.TOKENS.parent == module.VAR and module.MODEL_DIR.is_relative_to(module.VAR)
        module.use_var_dir()
        assert os.environ["VIGIL_DATABASE_URL"] == f"sqlite:///{module.VAR / 'vigil.db'}"
        for name in ("VIGIL_SECRET_KEY_FILE", "VIGIL_MODEL_STORE_DIR",
                     "VIGIL_LABELLING_MODEL_DIR", "VIGIL_ROBOT_MODELS_DIR"):  # fmt: skip
            assert os.environ[name].startswith(str(module.VAR)), name
        assert os.environ["VIGIL_ARCHIVE_DIR"] == "/elsewhere/archive"

        from backend.settings import Settings
        from robot_agent.config import AgentSettings

        assert Settings().model_store_dir == module.VAR / "models"
        assert AgentSettings().models_dir == module.VAR / "robot-models"
    finally:
        for name in ("VIGIL_DATABASE_URL", "VIGIL_SECRET_KEY_FILE", "VIGIL_MODEL_STORE_DIR",
                     "VIGIL_LABELLING_MODEL_DIR", "VIGIL_ROBOT_MODELS_DIR"):  # fmt: skip
            os.environ.pop(name, None)
        monkeypatch.delenv("VIGIL_VAR_DIR")
        importlib.reload(run_all)


def test_without_var_dir_the_settings_keep_their_own_defaults(monkeypatch):
    monkeypatch.delenv("VIGIL_VAR_DIR", raising=False)
    monkeypatch.delenv("VIGIL_DATABASE_URL", raising=False)
    module = importlib.reload(run_all)
    assert module.VAR == module.ROOT / "var"
    module.use_var_dir()
    assert "VIGIL_DATABASE_URL" not in os.environ  # a .env file may still set it
