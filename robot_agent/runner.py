"""Build one robot agent from its settings (`vigil-robot run`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_agent.agent import AgentOptions, RobotAgent
from robot_agent.config import AgentSettings, ConfigError, SourceKind
from robot_agent.models import Refusal, last_running, load_initial_model
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.source_factory import transports_for
from vigil.inputs import is_keypoints_only
from vigil.model_file import ModelIntegrityError
from vigil.runtime import FrameClassifier

DEFAULT_OUTBOX_DIR = Path("var/robot-outbox")


def initial_classifier(settings: AgentSettings, field: str = "model_dir") -> FrameClassifier | None:
    """The model of setting ``field`` (--model-dir), checked (exists, sha256, feature version,
    mode) or ConfigError naming the setting."""
    path = getattr(settings, field)
    try:
        classifier = load_initial_model(path)
    except FileNotFoundError as error:
        raise ConfigError(f"{field}: {error.filename or path} not found") from None
    except ModelIntegrityError as error:
        raise ConfigError(f"{field}: refused, {error}") from None
    except ValueError as error:
        raise ConfigError(f"{field}: {error}") from None
    if classifier is not None and classifier.manifest.mode != settings.mode:
        raise ConfigError(
            f"{field}: the model is for {classifier.manifest.mode.value} transports, "
            f"mode is {settings.mode.value}"
        )
    return classifier


def fallback_classifier(settings: AgentSettings) -> FrameClassifier | None:
    """The --fallback-model-dir model: checked like model_dir, and keypoints-only."""
    classifier = initial_classifier(settings, "fallback_model_dir")
    if classifier is not None and not is_keypoints_only(classifier.manifest.inputs):
        raise ConfigError(
            f"fallback_model_dir: model {classifier.manifest.version} needs "
            f"{', '.join(classifier.manifest.inputs)}; a fallback must need keypoints only"
        )
    return classifier


def starting_model(
    settings: AgentSettings, robot_id: str
) -> tuple[FrameClassifier | None, Refusal | None]:
    """(the model to start with, the remembered model refused at start if any): the model
    assigned by the backend before a restart (kept in models_dir) if it is still usable for this
    mode and its file is still the registry's, else the configured model_dir."""
    configured = initial_classifier(settings)  # checked even when not used: a clear error
    remembered, refusal = last_running(settings.models_dir / robot_id)
    if remembered is not None and remembered.manifest.mode == settings.mode:
        return remembered, None
    return configured, refusal


def starting_classifier(settings: AgentSettings, robot_id: str) -> FrameClassifier | None:
    return starting_model(settings, robot_id)[0]


def agent_options(settings: AgentSettings, speed: float | None = None) -> AgentOptions:
    return AgentOptions(
        url=settings.backend_urls,
        heartbeat_s=settings.heartbeat_s,
        batch_frames=settings.batch_frames,
        backoff_initial_s=settings.backoff_initial_s,
        backoff_max_s=settings.backoff_max_s,
        alarm_after_s=settings.alarm_after_s,
        alarm_hook=settings.alarm_hook,
        pause_hold_s=settings.pause_hold_s,
        degraded_action=settings.degraded_action,
        patient_unseen_s=settings.patient_unseen_s,
        local_socket=settings.local_socket,
        speed=settings.speed if speed is None else speed,
        exit_when_done=settings.exit_when_done,
    )


def source_inputs(settings: AgentSettings) -> list[str]:
    """What this robot's source can feed a model (vigil.inputs), told to the backend in the
    hello so that it assigns only models the robot can feed."""
    kind = settings.source
    if kind == SourceKind.GENERATED:  # the generator knows depth and its camera's mount
        return ["keypoints", "depth", "floor"]
    has_depth = settings.depth_dir is not None
    has_floor = has_depth and settings.mount is not None
    if kind == SourceKind.ROSBAG:  # depth from the depth topic; floor with CameraInfo + height
        has_depth = bool(settings.depth_topic)
        from_info = bool(settings.camera_info_topic) and bool(settings.camera_height_m)
        has_floor = has_depth and (from_info or settings.mount is not None)
    if kind == SourceKind.REPLAY:
        path = settings.source_path or ""
        if path.endswith(".json"):
            return _export_inputs(path) if Path(path).is_file() else ["keypoints"]
        has_floor = True  # a URFD recording carries URFD's own floor measures
    inputs = ["keypoints"]
    inputs += ["depth"] if has_depth else []
    inputs += ["floor"] if has_floor else []
    return inputs


def _export_inputs(path: str) -> list[str]:
    from robot_agent.sources.replay import VigilExportSource

    frames = VigilExportSource(path, speed=0).frames
    inputs = ["keypoints"]
    if any(np.isfinite(depth).any() for _, _, _, depth, _ in frames):
        inputs.append("depth")
    if any(not np.isnan(floor).all() for *_, floor in frames):
        inputs.append("floor")
    return inputs


def build_robot(settings: AgentSettings) -> RobotAgent:
    if not settings.robot_id:
        raise ConfigError("robot_id: required (flag --robot-id or VIGIL_ROBOT_ROBOT_ID)")
    token = settings.resolve_token()
    classifier, refusal = starting_model(settings, settings.robot_id)
    transports = transports_for(settings)
    outbox_path = settings.outbox_path or DEFAULT_OUTBOX_DIR / f"{settings.robot_id}.sqlite"
    outbox = Outbox(outbox_path, settings.outbox_budget_bytes)
    pipeline = Pipeline(
        outbox,
        settings.mode,
        classifier,
        ground_truth_fallback=settings.source == SourceKind.GENERATED,
        camera_mount=settings.mount,
        fallback=fallback_classifier(settings),
        available_inputs=source_inputs(settings),
    )
    if refusal is not None:  # never silent: a technical alarm once the backend hears of it
        pipeline.report_refusal(refusal.version, refusal.reason)
    # A camera paces itself; recorded, generated and video frames are paced by the agent.
    camera = settings.source == SourceKind.MEDIAPIPE and (settings.source_path or "").isdigit()
    speed = 0.0 if camera else settings.speed
    agent = RobotAgent(
        settings.robot_id,
        token,
        pipeline,
        transports,
        agent_options(settings, speed),
        settings.models_dir / settings.robot_id,
    )
    if settings.record_bag is not None:
        attach_recorder(agent, settings)
    return agent


def attach_recorder(agent: RobotAgent, settings: AgentSettings) -> None:
    """--record-bag: a new bag with the input bag's topics (rosbag source) and the agent's
    decisions and behaviour changes, finished when the source ends or the agent stops."""
    from robot_agent.sources.replay import SourceError
    from robot_agent.sources.rosbag import BagRecorder

    input_bag = settings.source_path if settings.source == SourceKind.ROSBAG else None
    try:
        recorder = BagRecorder(settings.record_bag, input_bag)
    except (OSError, SourceError) as error:
        raise ConfigError(f"record_bag: {error}") from None
    agent.pipeline.frame_listeners.append(recorder.on_frame)
    agent.behaviour.listeners.append(recorder.on_behaviour)
    agent.on_source_done.append(recorder.close)
