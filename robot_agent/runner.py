"""Run one robot: a source of camera frames -> FramePipeline -> outbox -> RobotClient."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterable, Iterator
from pathlib import Path

from robot_agent.client import Backoff, LocalAlarm, RobotClient
from robot_agent.config import RobotSettings, SourceKind
from robot_agent.models import ModelManager
from robot_agent.outbox import Outbox
from robot_agent.pipeline import FramePipeline
from robot_agent.sources import Observation
from vigil.classes import TransportMode
from vigil.runtime import FrameClassifier
from vigil.synthetic import Locomotion

log = logging.getLogger("robot_agent")
Transports = Iterable[tuple[TransportMode, Iterator[Observation]]]


def build_transports(settings: RobotSettings, seed: int = 0) -> Transports:
    """(mode, observations) per transport, from the configured source."""
    kind, path = settings.source, settings.source_path
    if kind is SourceKind.SIMULATOR:
        from robot_agent.sources.simulator import simulated_transports

        locomotions = simulator_locomotions(settings.mode)
        return (
            (
                loc.transport_mode
                if settings.mode is not TransportMode.COMBINED
                else settings.mode,
                obs,
            )
            for loc, obs in simulated_transports(seed, locomotions, count=settings.transports)
        )
    if not path:
        raise ValueError(f"source_path: needed for source {kind.value}")
    if kind is SourceKind.URFD:
        from robot_agent.sources.replay import replay_urfd

        return [(settings.mode, replay_urfd(path))]
    if kind is SourceKind.EXPORT:
        from robot_agent.sources.replay import replay_vigil_export

        return [(settings.mode, replay_vigil_export(path))]
    if kind is SourceKind.OPENPOSE:
        from robot_agent.sources.openpose_dir import openpose_dir

        return [(settings.mode, openpose_dir(path, settings.depth_dir))]
    from robot_agent.sources.mediapipe_video import mediapipe_video

    video: str | int = int(path) if path.isdigit() else path
    return [(settings.mode, mediapipe_video(video, crop=settings.crop))]


def simulator_locomotions(mode: TransportMode) -> tuple[Locomotion, ...]:
    if mode is TransportMode.WALKING:
        return (Locomotion.WALKING, Locomotion.ROLLATOR)
    if mode is TransportMode.WHEELCHAIR:
        return (Locomotion.WHEELCHAIR,)
    return (Locomotion.WALKING, Locomotion.WHEELCHAIR, Locomotion.ROLLATOR)


def build_models(model_dir: Path | None, models_dir: Path) -> ModelManager | None:
    if model_dir is None:
        return None
    classifier = FrameClassifier.from_dir(model_dir)
    log.info(
        "loaded model %s (%s, threshold %.3f, delay %d ms)",
        classifier.manifest.version,
        classifier.manifest.mode.value,
        classifier.manifest.threshold,
        classifier.manifest.delay_ms,
    )
    return ModelManager(models_dir, classifier)


async def stream(
    pipeline: FramePipeline,
    client: RobotClient,
    alarm: LocalAlarm,
    transports: Transports,
    stop: asyncio.Event,
    speed: float = 1.0,
) -> int:
    """Feed every transport through the pipeline, paced at ``speed`` x real time."""
    loop = asyncio.get_running_loop()
    frames = 0
    for mode, observations in transports:
        if stop.is_set():
            break
        pipeline.start_transport(mode)
        client.notify()
        start = loop.time()
        for obs in observations:
            if stop.is_set():
                break
            delay = start + obs.timestamp / speed - loop.time()
            await asyncio.sleep(max(delay, 0.0))
            if pipeline.process(obs) is not None:
                frames += 1
            client.notify()
            alarm.update(pipeline.emergency_holds, client.connected)
        pipeline.end_transport()
        client.notify()
    return frames


async def run_robot(settings: RobotSettings, stop: asyncio.Event | None = None) -> int:
    stop = stop or asyncio.Event()
    models = None
    if not settings.ground_truth:
        models = build_models(settings.model_dir, settings.models_dir)
    outbox = Outbox(settings.outbox_path, settings.outbox_max_frames)
    pipeline = FramePipeline(
        outbox, models, settings.mode, settings.ground_truth, settings.depth_mm_per_unit
    )
    client = RobotClient(
        settings.backend_url,
        settings.robot_id,
        settings.token,
        outbox,
        models,
        settings.heartbeat_s,
        Backoff(cap_s=settings.backoff_cap_s),
    )
    alarm = LocalAlarm(settings.robot_id, settings.alarm_hook, settings.alarm_grace_s)
    client_task = asyncio.create_task(client.run(stop))
    try:
        frames = await stream(
            pipeline, client, alarm, build_transports(settings), stop, settings.speed
        )
        log.info(
            "source finished after %d frames; waiting for the backend to acknowledge %d",
            frames,
            len(outbox),
        )
        deadline = asyncio.get_running_loop().time() + settings.drain_timeout_s
        while len(outbox) and not stop.is_set() and not client_task.done():
            if asyncio.get_running_loop().time() > deadline:
                log.warning(
                    "%d frames are still unacknowledged; they stay in %s and are sent "
                    "at the next start",
                    len(outbox),
                    settings.outbox_path,
                )
                break
            await asyncio.sleep(0.1)
        return frames
    finally:
        stop.set()
        await asyncio.gather(client_task, return_exceptions=False)
        outbox.close()
