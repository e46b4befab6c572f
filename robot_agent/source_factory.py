"""Turn the configured source into transports for the agent."""

from __future__ import annotations

import importlib
import itertools
from collections.abc import Iterator

from robot_agent.agent import TransportPlan
from robot_agent.config import AgentSettings, ConfigError, SourceKind

GENERATED_LOCATION = "simulated corridor (GENERATED data)"


def generated_transports(
    seed: int,
    locomotion: str = "walking",
    events: list[str] | None = None,
    count: int | None = None,
    n_people: int = 3,
    duration_s: float = 30.0,
    patient_prefix: str = "GEN",
) -> Iterator[TransportPlan]:
    """GENERATED transports (robot_agent.sources.simulator), one plan per transport; the agent
    paces them, the simulator itself runs flat out (speed 0)."""
    from robot_agent.sources.simulator import SimulatorSource

    numbers = itertools.count() if count is None else range(count)
    for number in numbers:
        source = SimulatorSource(
            mode=locomotion,
            seed=seed + number,
            duration_s=duration_s,
            n_people=n_people,
            events=events,
            transports=1,
            speed=0,
        )
        yield TransportPlan(
            source,
            patient=f"{patient_prefix}-{(seed + number) % 1000:03d}",
            location=GENERATED_LOCATION,
            materialise=True,
        )


def _module(name: str, kind: SourceKind):
    try:
        return importlib.import_module(f"robot_agent.sources.{name}")
    except ImportError as error:
        raise ConfigError(f"source: {kind.value} is not available here ({error})") from None


def transports_for(settings: AgentSettings) -> Iterator[TransportPlan]:
    """The transports of `vigil-robot run`: the whole source is one transport (a new one each
    time it starts again with `loop`)."""
    kind = settings.source
    if kind == SourceKind.GENERATED:
        events = [settings.scenario] if settings.scenario else None
        count = None if settings.loop else 1
        return generated_transports(
            settings.seed, "walking" if settings.mode == "walking" else "wheelchair", events, count
        )
    if settings.source_path is None:
        raise ConfigError(f"source_path: required for source {kind.value}")
    path = settings.source_path
    if kind == SourceKind.REPLAY:
        module = _module("replay", kind)
        if path.endswith(".json"):  # a Vigil label export

            def make():
                return module.VigilExportSource(path, speed=0)
        else:  # a URFD sequence name, e.g. fall-01 (real data)

            def make():
                return module.UrfdReplaySource(
                    path.removeprefix("urfd:"), speed=0, depth_dir=settings.depth_dir
                )
    elif kind == SourceKind.OPENPOSE:
        module = _module("openpose_dir", kind)

        def make():
            return module.OpenPoseDirSource(
                path, depth_dir=settings.depth_dir, depth_scale_mm=settings.depth_scale_mm
            )
    else:
        module = _module("mediapipe_video", kind)
        video = int(path) if path.isdigit() else path  # a number is a camera index
        crop = module.parse_crop(settings.crop) if settings.crop else None

        def make():
            return module.MediaPipeVideoSource(video, crop=crop)

    try:
        make()  # a bad path fails now, naming the field, not in the middle of a run
    except (OSError, ValueError) as error:
        raise ConfigError(f"source_path: {error}") from None

    def plans() -> Iterator[TransportPlan]:
        while True:
            yield TransportPlan(make(), patient=settings.patient, location=settings.location)
            if not settings.loop:
                return

    return plans()
