"""`make run`'s supervisor on another data directory (VIGIL_VAR_DIR), as bench/demo_hour.py
runs it: every child's settings point there; settings given in the environment stay."""

from __future__ import annotations

import importlib
import os

import scripts.run_all as run_all


def test_var_dir_moves_everything_make_run_writes(tmp_path, monkeypatch):
    for name in (
        "VIGIL_DATABASE_URL",
        "VIGIL_SECRET_KEY_FILE",
        "VIGIL_MODEL_STORE_DIR",
        "VIGIL_LABELLING_MODEL_DIR",
        "VIGIL_ARCHIVE_DIR",
        "VIGIL_ROBOT_MODELS_DIR",
    ):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("VIGIL_VAR_DIR", str(tmp_path / "var"))
    monkeypatch.setenv("VIGIL_ARCHIVE_DIR", "/elsewhere/archive")  # given: kept
    module = importlib.reload(run_all)
    try:
        assert (tmp_path / "var").resolve() == module.VAR
        assert module.TOKENS.parent == module.VAR and module.MODEL_DIR.is_relative_to(module.VAR)
        module.use_var_dir()
        assert os.environ["VIGIL_DATABASE_URL"] == f"sqlite:///{module.VAR / 'vigil.db'}"
        for name in (
            "VIGIL_SECRET_KEY_FILE",
            "VIGIL_MODEL_STORE_DIR",
            "VIGIL_LABELLING_MODEL_DIR",
            "VIGIL_ROBOT_MODELS_DIR",
        ):
            assert os.environ[name].startswith(str(module.VAR)), name
        assert os.environ["VIGIL_ARCHIVE_DIR"] == "/elsewhere/archive"

        from backend.settings import Settings
        from robot_agent.config import AgentSettings

        assert Settings().model_store_dir == module.VAR / "models"
        assert AgentSettings().models_dir == module.VAR / "robot-models"
    finally:
        for name in (
            "VIGIL_DATABASE_URL",
            "VIGIL_SECRET_KEY_FILE",
            "VIGIL_MODEL_STORE_DIR",
            "VIGIL_LABELLING_MODEL_DIR",
            "VIGIL_ROBOT_MODELS_DIR",
        ):
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


def test_the_demo_models_must_be_trained_with_the_generated_walking_transports(tmp_path):
    """make run's robots stream GENERATED patients: a model trained on URFD alone (an older
    var/models) is trained again, with --with-generated; one trained so is kept."""
    from tests.robot_agent.tiny_model import upright_model_bytes
    from vigil.classes import Decision, TransportMode
    from vigil.datasets import urfd
    from vigil.features import FEATURE_VERSION
    from vigil.model_file import ModelManifest, write_model
    from vigil.taxonomy import DEFAULT_TAXONOMY

    train, gold = urfd.split()

    def write(directory, dataset: str, trained_on: list[str] | None = train):
        manifest = ModelManifest(
            version=f"m-{dataset}",
            name="m",
            mode=TransportMode.WALKING,
            classes=[Decision.NORMAL, Decision.EMERGENCY],
            feature_version=FEATURE_VERSION,
            feature_set="pose",
            taxonomy_version=DEFAULT_TAXONOMY.version,
            threshold=0.5,
            delay_ms=200,
            metrics={"dataset": dataset, "training_recordings": trained_on},
            training_data_sha256="0" * 64,
            generated_data=dataset != "urfd",
            sha256="0" * 64,
        )
        write_model(directory, upright_model_bytes(), manifest)
        return directory

    urfd_only = write(tmp_path / "urfd", "urfd")
    demo = write(tmp_path / "demo", "urfd+generated")
    assert run_all.model_is_current(urfd_only) and not run_all.model_is_current(urfd_only, True)
    assert run_all.model_is_current(demo, demo=True)
    assert not run_all.model_is_current(tmp_path / "missing", demo=True)
    # A model trained on the gold set too, or with no record of what it was trained on (made
    # before the split was kept), is trained again.
    on_everything = write(tmp_path / "all", "urfd+generated", [*train, gold[0]])
    assert not run_all.model_is_current(on_everything, demo=True)
    assert not run_all.model_is_current(write(tmp_path / "old", "urfd+generated", None), True)


def test_fleet_banner_prints_the_rates_in_force(monkeypatch):
    monkeypatch.setenv("VIGIL_ROBOT_FALLS_PER_HOUR", "12")
    monkeypatch.setenv("VIGIL_ROBOT_LOOKALIKES_PER_HOUR", "0")
    banner = run_all.fleet_banner()
    assert "12 falls" in banner and "0 look-alikes" in banner and "3 Pause" in banner
    assert "15 min" not in banner


def test_make_run_starts_the_alert_manager_simulator_and_points_the_backend_at_it(monkeypatch):
    from backend.demo import DEMO_WARD
    from backend.settings import Settings

    for name in ("VIGIL_ALERT_MANAGER", "VIGIL_ALERT_STATUS_LISTEN", "VIGIL_DEMO_PHONE_ACCEPT_S"):
        monkeypatch.setenv(name, "")  # recorded, so what the function sets is undone afterwards
        monkeypatch.delenv(name)
    arguments = run_all.alert_manager_simulator()
    assert arguments[:2] == ["-m", "scripts.alert_manager_simulator"]
    assert arguments[arguments.index("--listen") + 1] == run_all.ALERT_MANAGER
    assert arguments[arguments.index("--vigil") + 1] == run_all.ALERT_STATUS_LISTEN
    assert arguments[arguments.index("--ward-phone") + 1].startswith(f"{DEMO_WARD}=")
    assert "--accept-after" not in arguments  # the nurse acknowledges, unless asked otherwise
    settings = Settings()
    assert settings.alert_manager == run_all.ALERT_MANAGER
    assert settings.alert_status_listen == run_all.ALERT_STATUS_LISTEN


def test_a_real_alert_manager_in_the_environment_means_no_simulator(monkeypatch):
    monkeypatch.setenv("VIGIL_ALERT_MANAGER", "10.1.3.7:2575")
    assert run_all.alert_manager_simulator() is None
    assert os.environ["VIGIL_ALERT_MANAGER"] == "10.1.3.7:2575"


def test_the_simulated_phone_accepts_only_when_asked(monkeypatch):
    for name in ("VIGIL_ALERT_MANAGER", "VIGIL_ALERT_STATUS_LISTEN"):
        monkeypatch.setenv(name, "")
        monkeypatch.delenv(name)
    monkeypatch.setenv("VIGIL_DEMO_PHONE_ACCEPT_S", "45")
    arguments = run_all.alert_manager_simulator()
    assert arguments[arguments.index("--accept-after") + 1] == "45"
