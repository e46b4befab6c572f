"""The agent's settings: a TOML config file, then VIGIL_ROBOT_* environment variables, then
command-line flags (each later one wins). Unknown keys and bad values are refused with the name
of the field (ConfigError), which the CLI prints before exiting with code 2."""

from __future__ import annotations

import tomllib
from enum import StrEnum
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, field_validator, model_validator
from pydantic_settings import (
    BaseSettings,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)

from robot_agent.behaviour import DegradedAction
from vigil.classes import TransportMode
from vigil.floor import CameraMount

ENV_PREFIX = "VIGIL_ROBOT_"
DEFAULT_VAR = Path("var")


class SourceKind(StrEnum):
    GENERATED = "generated"  # the transport simulator (GENERATED data, for demos and load)
    REPLAY = "replay"  # a URFD keypoint file or a Vigil export
    OPENPOSE = "openpose"  # a directory of OpenPose JSON files (+ optional depth PNGs)
    MEDIAPIPE = "mediapipe"  # a video file or camera index through MediaPipe pose
    ROSBAG = "rosbag"  # a ROS 2 recording (RGB, aligned depth, camera info) through MediaPipe


def parse_camera_mount(text: str) -> CameraMount:
    """``"fx,fy,cx,cy,height_m,pitch_deg"`` -> CameraMount (ValueError naming what is wrong)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as error:
        raise ValueError("expected numbers fx,fy,cx,cy,height_m,pitch_deg") from error
    if len(values) != 6:
        raise ValueError(f"expected 6 numbers fx,fy,cx,cy,height_m,pitch_deg, got {len(values)}")
    return CameraMount(*values)


class ConfigError(Exception):
    """A configuration value is missing or invalid; the message names the field."""


class AgentSettings(BaseSettings):
    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX, extra="forbid", validate_default=True, toml_file=None
    )

    backend_url: str = Field(
        default="ws://127.0.0.1:8000/ws/robot",
        description="the backend's robot websocket; several replicas comma-separated, tried "
        "in turn (a lost connection goes to the next at once)",
    )
    robot_id: str | None = Field(default=None, max_length=64, description="this robot's id")
    token: str | None = Field(default=None, max_length=256, description="this robot's token")
    token_file: Path | None = Field(
        default=None, description="file holding the token (plain, or JSON {robot_id: token})"
    )
    mode: TransportMode = Field(default=TransportMode.WALKING, description="transport mode")
    source: SourceKind = Field(default=SourceKind.GENERATED, description="keypoint source")
    source_path: str | None = Field(
        default=None,
        description="replay: URFD sequence (fall-01, or FILE#fall-01 for a keypoint file in "
        "URFD's format) or export .json; openpose: directory; "
        "mediapipe: video file or camera index; rosbag: the rosbag2 directory",
    )
    rgb_topic: str = Field(
        default="/camera/color/image_raw",
        min_length=1,
        description="rosbag: RGB topic (sensor_msgs/msg/Image or CompressedImage)",
    )
    depth_topic: str = Field(
        default="/camera/aligned_depth_to_color/image_raw",
        description="rosbag: aligned depth topic (sensor_msgs/msg/Image 16UC1 mm or 32FC1 m; "
        "empty: none)",
    )
    camera_info_topic: str = Field(
        default="/camera/color/camera_info",
        description="rosbag: sensor_msgs/msg/CameraInfo topic (empty: none)",
    )
    depth_tolerance_s: float = Field(
        default=0.02,
        ge=0,
        description="rosbag: a depth picture pairs with the RGB frame of the nearest stamp "
        "within this many seconds",
    )
    camera_height_m: float | None = Field(
        default=None,
        gt=0,
        description="rosbag: camera height above the floor; with CameraInfo gives floor measures",
    )
    camera_pitch_deg: float = Field(
        default=0.0, gt=-90, lt=90, description="rosbag: downward tilt of the camera"
    )
    record_bag: Path | None = Field(
        default=None,
        description="write a new rosbag2 here: the input bag's topics plus /vigil/decision "
        "and /vigil/behaviour (std_msgs/msg/String JSON)",
    )
    depth_dir: Path | None = Field(
        default=None, description="16-bit depth PNGs (openpose, URFD replay)"
    )
    depth_scale_mm: float = Field(
        default=1.0, gt=0, description="raw depth value -> millimetres (openpose depth PNGs)"
    )
    crop: str | None = Field(
        default=None, description="mediapipe: x,y,width,height of the frame to use"
    )
    camera_mount: str | None = Field(
        default=None,
        description="depth camera over the floor: fx,fy,cx,cy,height_m,pitch_deg (pixels of the "
        "keypoints; metres; degrees down); gives frames floor measures",
    )
    speed: float = Field(
        default=1.0, ge=0, description="replay speed (1 = real time, 0 = as fast as possible)"
    )
    loop: bool = Field(default=False, description="start the source again when it ends")
    scenario: str | None = Field(default=None, description="generated source: one scenario")
    seed: int = Field(default=0, description="generated source: random seed")
    duration_s: float = Field(
        default=30.0, gt=0, description="generated source: length of a transport in seconds"
    )
    people: int = Field(default=3, ge=1, le=5, description="generated source: people in view")
    falls_per_hour: float = Field(
        default=4.0,
        ge=0,
        description="simulated fleet: Emergencies (falls, stumbles; slumps in "
        "a wheelchair) per robot per hour; the default, one every 15 min, is a believable ward",
    )
    pauses_per_hour: float = Field(
        default=3.0,
        ge=0,
        description="simulated fleet: Pause situations (too far away, standing "
        "up from the wheelchair, crushing hazard) per robot per hour",
    )
    lookalikes_per_hour: float = Field(
        default=6.0,
        ge=0,
        description="simulated fleet: look-alikes of a fall (bending, sitting "
        "down, lying down on a bed) per robot per hour",
    )
    patient: str | None = Field(default=None, max_length=64, description="patient pseudonym")
    location: str | None = Field(default=None, max_length=128)
    model_dir: Path | None = Field(
        default=None, description="model to start with (manifest.json + model.onnx)"
    )
    fallback_model_dir: Path | None = Field(
        default=None,
        description="keypoints-only model to decide with when the model lacks an input "
        "(the backend sends one too)",
    )
    models_dir: Path = Field(
        default=DEFAULT_VAR / "robot-models", description="where assigned models are stored"
    )
    outbox_path: Path | None = Field(
        default=None, description="outbox SQLite file (default var/robot-outbox/<robot>.sqlite)"
    )
    outbox_budget_bytes: int = Field(
        default=200_000_000, gt=0, description="disk budget of the outbox (message bytes)"
    )
    heartbeat_s: float = Field(default=5.0, gt=0, description="heartbeat interval")
    batch_frames: int = Field(default=100, ge=1, le=500, description="frames per batch")
    backoff_initial_s: float = Field(default=0.5, gt=0, description="first reconnect delay")
    backoff_max_s: float = Field(default=15.0, gt=0, description="longest reconnect delay")
    alarm_after_s: float = Field(
        default=3.0, ge=0, description="unacknowledged Emergency age that raises the local alarm"
    )
    alarm_hook: str | None = Field(
        default=None, description="command run when the local alarm is raised or cleared"
    )
    pause_hold_s: float = Field(
        default=2.0, ge=0, description="Normal decisions needed this long before a pause resumes"
    )
    degraded_action: DegradedAction = Field(
        default=DegradedAction.STOP,
        description="what the robot does while detection is degraded: slow or stop",
    )
    patient_unseen_s: float = Field(
        default=3.0, gt=0, description="patient not seen this long: detection degraded"
    )
    local_socket: Path | None = Field(
        default=None,
        description="UNIX socket streaming behaviour changes to the robot's controller",
    )
    exit_when_done: bool = Field(
        default=False, description="exit once the source ended and the outbox is empty"
    )
    log_level: str = Field(default="INFO", description="DEBUG, INFO, WARNING or ERROR")

    @field_validator("backend_url")
    @classmethod
    def _websocket_url(cls, value: str) -> str:
        urls = [part.strip() for part in value.split(",")]
        for url in urls:
            if not url.startswith(("ws://", "wss://")):
                raise ValueError(f"each URL must start with ws:// or wss:// (got {url!r})")
        return ",".join(urls)

    @property
    def backend_urls(self) -> list[str]:
        return self.backend_url.split(",")

    @field_validator("camera_mount")
    @classmethod
    def _mount(cls, value: str | None) -> str | None:
        if value is not None:
            parse_camera_mount(value)
        return value

    @property
    def mount(self) -> CameraMount | None:
        return parse_camera_mount(self.camera_mount) if self.camera_mount else None

    @field_validator("log_level")
    @classmethod
    def _level(cls, value: str) -> str:
        if value.upper() not in ("DEBUG", "INFO", "WARNING", "ERROR"):
            raise ValueError("must be DEBUG, INFO, WARNING or ERROR")
        return value.upper()

    @model_validator(mode="after")
    def _consistent(self) -> AgentSettings:
        if self.backoff_max_s < self.backoff_initial_s:
            raise ValueError("backoff_max_s must not be smaller than backoff_initial_s")
        return self

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        return (init_settings, env_settings, TomlConfigSettingsSource(settings_cls))

    def resolve_token(self, robot_id: str | None = None) -> str:
        """The token for `robot_id` (default: this robot) from `token` or `token_file`."""
        robot_id = robot_id or self.robot_id
        if self.token and robot_id == self.robot_id:
            return self.token
        if self.token_file is None:
            raise ConfigError("token: set token or token_file")
        return read_token(self.token_file, robot_id)


def read_token(path: Path, robot_id: str | None) -> str:
    import json

    try:
        text = path.read_text().strip()
    except OSError as error:
        raise ConfigError(f"token_file: cannot read {path}: {error.strerror}") from None
    if text.startswith("{"):
        try:
            tokens = json.loads(text)
        except json.JSONDecodeError as error:
            raise ConfigError(f"token_file: {path} is not valid JSON: {error}") from None
        if robot_id not in tokens:
            raise ConfigError(f"token_file: {path} has no token for robot {robot_id!r}")
        return str(tokens[robot_id])
    if not text:
        raise ConfigError(f"token_file: {path} is empty")
    return text


def read_tokens(path: Path) -> dict[str, str]:
    """A fleet's tokens: JSON {robot_id: token} as `backend.cli seed-demo` writes it."""
    import json

    try:
        tokens = json.loads(path.read_text())
    except OSError as error:
        raise ConfigError(f"tokens_file: cannot read {path}: {error.strerror}") from None
    except json.JSONDecodeError as error:
        raise ConfigError(f"tokens_file: {path} is not valid JSON: {error}") from None
    if not isinstance(tokens, dict) or not tokens:
        raise ConfigError(f"tokens_file: {path} must be a JSON object {{robot_id: token}}")
    return {str(k): str(v) for k, v in tokens.items()}


def describe_error(error: ValidationError) -> str:
    """'bad configuration: outbox_budget_bytes: Input should be greater than 0 (got -5)'."""
    lines = []
    for problem in error.errors():
        field = ".".join(str(part) for part in problem["loc"]) or "configuration"
        got = problem.get("input")
        shown = "" if isinstance(got, dict) or got is None else f" (got {got!r})"
        message = problem["msg"].removeprefix("Value error, ")
        if problem["type"] == "extra_forbidden":
            message = "unknown setting"
        lines.append(f"{field}: {message}{shown}")
    return "bad configuration: " + "; ".join(lines)


def load_settings(config_file: Path | None = None, **overrides: Any) -> AgentSettings:
    """Settings from the config file (TOML), VIGIL_ROBOT_* variables and explicit overrides
    (flags that were given; None means 'not given'). Raises ConfigError naming the field."""
    overrides = {k: v for k, v in overrides.items() if v is not None}
    toml_file = None
    if config_file is not None:
        if not config_file.is_file():
            raise ConfigError(f"config: file {config_file} not found")
        try:
            with config_file.open("rb") as handle:
                tomllib.load(handle)
        except tomllib.TOMLDecodeError as error:
            raise ConfigError(f"config: {config_file} is not valid TOML: {error}") from None
        toml_file = config_file
    settings_class = type(
        "AgentSettings",
        (AgentSettings,),
        {"model_config": {**AgentSettings.model_config, "toml_file": toml_file}},
    )
    try:
        return settings_class(**overrides)
    except ValidationError as error:
        raise ConfigError(describe_error(error)) from None
