"""Robot agent settings: environment (VIGIL_ROBOT_*), a TOML or JSON config file, then flags."""

from __future__ import annotations

import json
import tomllib
from enum import StrEnum
from pathlib import Path

from pydantic import Field, ValidationError, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from vigil.classes import TransportMode


class SourceKind(StrEnum):
    SIMULATOR = "simulator"
    URFD = "urfd"
    EXPORT = "export"
    OPENPOSE = "openpose"
    MEDIAPIPE = "mediapipe"


class RobotSettings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="VIGIL_ROBOT_", extra="forbid")

    backend_url: str = Field("ws://127.0.0.1:8000/ws/robot", description="robot websocket URL")
    robot_id: str = Field("robot-1", min_length=1, max_length=64)
    token: str = Field("", max_length=256, description="this robot's own token")
    mode: TransportMode = TransportMode.WALKING
    source: SourceKind = SourceKind.SIMULATOR
    source_path: str | None = Field(
        None, description="URFD sequence name, export file, OpenPose dir, video file or camera"
    )
    depth_dir: Path | None = Field(None, description="16-bit depth PNGs next to an OpenPose dir")
    depth_mm_per_unit: float = Field(1.0, gt=0, description="URFD falls: 6000/65535")
    crop: str = Field("full", pattern="^(full|left|right)$", description="video half to use")
    model_dir: Path | None = Field(None, description="directory with manifest.json + model.onnx")
    models_dir: Path = Field(Path("var/robot/models"), description="where downloads are kept")
    ground_truth: bool = Field(False, description="stream generated ground truth, no model")
    outbox_path: Path = Field(Path("var/robot/outbox.sqlite"))
    outbox_max_frames: int = Field(200_000, ge=100)
    speed: float = Field(1.0, gt=0, description="1 = real time; 0 < speed; larger is faster")
    heartbeat_s: float = Field(5.0, gt=0)
    backoff_cap_s: float = Field(10.0, gt=0)
    alarm_hook: str | None = Field(None, description="command run on a local alarm")
    alarm_grace_s: float = Field(2.0, ge=0)
    transports: int | None = Field(None, ge=1, description="stop after this many (simulator)")
    drain_timeout_s: float = Field(
        60.0, ge=0, description="after the source ends, wait this long for the last acks"
    )
    log_level: str = "INFO"

    @field_validator("backend_url")
    @classmethod
    def _websocket_url(cls, value: str) -> str:
        if not value.startswith(("ws://", "wss://")):
            raise ValueError("must start with ws:// or wss://")
        return value


def read_config_file(path: Path) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"config file {path} does not exist")
    text = path.read_text()
    data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    return data.get("robot", data)


def load_settings(config_file: Path | None, overrides: dict) -> RobotSettings:
    """File values, then flags on top; raises ValidationError naming the bad field."""
    values = read_config_file(config_file) if config_file else {}
    values.update({k: v for k, v in overrides.items() if v is not None})
    return RobotSettings(**values)


def describe_error(error: ValidationError) -> str:
    parts = []
    for item in error.errors():
        name = ".".join(str(p) for p in item["loc"]) or "config"
        parts.append(f"{name}: {item['msg']}")
    return "; ".join(parts)
