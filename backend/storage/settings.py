"""Retention settings, shared by the backend (dry run, the admin page) and the worker (the
scheduled run): one mixin both settings classes inherit, so the names are the same."""

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings

REPO_ROOT = Path(__file__).resolve().parent.parent.parent


class StorageSettings(BaseSettings):
    retention_days: float = Field(
        default=30,
        gt=0,
        description="robot frames older than this many days are dropped unless the policy keeps "
        "them (alarm windows, labelled or split videos, registered models' training videos)",
    )
    retention_alarm_before_s: float = Field(
        default=60, ge=0, description="frames kept forever before each alarm's first frame"
    )
    retention_alarm_after_s: float = Field(
        default=30, ge=0, description="frames kept forever after each alarm's last frame"
    )
    retention_downsample_fps: float = Field(
        default=0,
        ge=0,
        description="keep a downsampled copy (this many frames per second) of what would be "
        "dropped, for retention_downsample_days more days; 0: off",
    )
    retention_downsample_days: float = Field(
        default=60, ge=0, description="how long the downsampled copy is kept after the cutoff"
    )
    retention_interval_h: float = Field(
        default=24, gt=0, description="the worker queues a retention run this often"
    )
    retention_chunk_rows: int = Field(
        default=2000,
        ge=1,
        description="SQLite: frames checked in the first delete chunk; the next chunks adapt "
        "to retention_chunk_hold_ms",
    )
    retention_chunk_hold_ms: float = Field(
        default=30,
        gt=0,
        description="SQLite: how long one delete chunk (the delete, then the incremental vacuum) "
        "may hold the write lock; the chunk size grows or shrinks to keep near it",
    )
    retention_chunk_pause_ms: float = Field(
        default=20, ge=0, description="SQLite: pause between delete chunks (lets ingest commit)"
    )
    partitions_ahead_days: int = Field(
        default=7, ge=1, description="PostgreSQL: day partitions of frames created ahead"
    )
    storage_summary_ttl_s: float = Field(
        default=60,
        ge=0,
        description="the storage figures (page, /metrics) are recomputed at "
        "most this often (they scan every frame)",
    )
    archive_dir: Path = Field(
        default=REPO_ROOT / "var" / "archive", description="Parquet archives of videos"
    )
