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
    if kind == SourceKind.REPLAY:
        module = _module("replay", kind)
        make = lambda: module.open_replay(settings.source_path, speed=0)  # noqa: E731
    elif kind == SourceKind.OPENPOSE:
        module = _module("openpose_dir", kind)
        make = lambda: module.OpenPoseDirSource(  # noqa: E731
            settings.source_path, depth_dir=settings.depth_dir, speed=0
        )
    else:
        module = _module("mediapipe_video", kind)
        make = lambda: module.MediaPipeSource(settings.source_path)  # noqa: E731
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
