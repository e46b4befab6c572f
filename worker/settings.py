"""Worker settings: one pydantic-settings class, read from VIGIL_* environment variables
(database_url and model_store_dir are the backend's own names, so one .env serves both)."""

from pathlib import Path

from pydantic import Field
from pydantic_settings import SettingsConfigDict

from backend.storage.settings import StorageSettings

REPO_ROOT = Path(__file__).resolve().parent.parent


class WorkerSettings(StorageSettings):
    model_config = SettingsConfigDict(env_prefix="VIGIL_", env_file=".env", extra="ignore")

    database_url: str = Field(
        default=f"sqlite:///{REPO_ROOT / 'var' / 'vigil.db'}", description="SQLAlchemy URL"
    )
    model_store_dir: Path = Field(
        default=REPO_ROOT / "var" / "models", description="registered model files"
    )
    worker_id: str | None = Field(default=None, description="default: host:pid")
    worker_poll_s: float = Field(default=1.0, description="idle wait between queue polls")
    worker_heartbeat_s: float = Field(default=2.0, description="heartbeat period of a running job")
    worker_stale_after_s: float = Field(
        default=30.0, description="a running job without heartbeat for this long is taken over"
    )
    worker_max_attempts: int = Field(default=3, description="claims of one job before it fails")
    worker_sweep_s: float = Field(
        default=10.0, description="period of the shadow-disagreement and auto-rollback sweeps"
    )
    dask_scheduler: str | None = Field(
        default=None,
        description="tcp://host:port of a Dask scheduler: the grid search runs on that cluster",
    )
    grid_n_jobs: int = Field(default=1, description="local processes for the grid search")
    false_alarm_budget: float = Field(
        default=0.3,
        description="share of nurse-rejected alarms of a new version that triggers a rollback",
    )
    false_alarm_min_verdicts: int = Field(
        default=5, description="verdicts needed before the automatic rollback may act"
    )
