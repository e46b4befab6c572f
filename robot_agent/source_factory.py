"""Turn the configured source into transports for the agent."""

from __future__ import annotations

import importlib
import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from robot_agent.agent import TransportPlan
from robot_agent.config import AgentSettings, ConfigError, SourceKind

GENERATED_LOCATION = "simulated corridor (GENERATED data)"


@dataclass(frozen=True, slots=True)
class EventRates:
    """How often a simulated robot meets each kind of situation, per hour of transports."""

    falls_per_hour: float = 4.0
    pauses_per_hour: float = 3.0
    lookalikes_per_hour: float = 6.0


#: Situations per kind, of those the generator knows for a locomotion (vigil.synthetic).
PAUSE_EVENTS = ("too_far_away", "standing_up_from_wheelchair", "crushing_hazard")
LOOKALIKE_EVENTS = ("bending", "sitting_down", "lying_down_deliberately")
ROUTINE_EVENTS = ("turning", "gesturing", "standing")


def ward_events(rng, locomotion: str, transport_s: float, rates: EventRates) -> list[str]:
    """The events of one GENERATED transport of `transport_s` seconds: at most one situation,
    drawn so that each kind happens at its rate per hour; otherwise routine movement."""
    from vigil.synthetic import EMERGENCY_EVENTS, EVENTS_BY_LOCOMOTION, Locomotion

    loc = Locomotion(locomotion)
    known = EVENTS_BY_LOCOMOTION[loc]
    kinds = [
        (rates.falls_per_hour, EMERGENCY_EVENTS[loc]),
        (rates.pauses_per_hour, tuple(e for e in PAUSE_EVENTS if e in known)),
        (rates.lookalikes_per_hour, tuple(e for e in LOOKALIKE_EVENTS if e in known)),
    ]
    draw = rng.random()
    for per_hour, events in kinds:
        chance = per_hour * transport_s / 3600
        if draw < chance and events:
            return [events[int(rng.integers(len(events)))]]
        draw -= chance
    routine = [e for e in ROUTINE_EVENTS if e in known]
    return [routine[int(rng.integers(len(routine)))]]


def generated_transports(
    seed: int,
    locomotion: str = "walking",
    events: list[str] | None = None,
    count: int | None = None,
    n_people: int = 3,
    duration_s: float = 30.0,
    patient_prefix: str = "GEN",
    rates: EventRates | None = None,
) -> Iterator[TransportPlan]:
    """GENERATED transports (robot_agent.sources.simulator), one plan per transport; the agent
    paces them, the simulator itself runs flat out (speed 0). With `rates` each transport's
    events are drawn at those rates (`ward_events`); else `events` (None: the generator picks,
    always with an Emergency)."""
    import numpy as np

    from robot_agent.sources.simulator import SimulatorSource

    numbers = itertools.count() if count is None else range(count)
    for number in numbers:
        if rates is not None:
            rng = np.random.default_rng([seed, number, 21])
            events = ward_events(rng, locomotion, duration_s, rates)
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
            fps=source.fps,
            generated_events=tuple(events or ()),
        )


def _module(name: str, kind: SourceKind):
    try:
        return importlib.import_module(f"robot_agent.sources.{name}")
    except ImportError as error:
        raise ConfigError(f"source: {kind.value} is not available here ({error})") from None


def _urfd_sequence(path: str) -> tuple[str, str | None]:
    """``fall-01`` / ``urfd:fall-01`` (the dataset's own file), ``FILE#fall-01``, or ``FILE``
    holding a single sequence -> (sequence, keypoint file or None)."""
    file, _, sequence = path.partition("#")
    if not Path(file).is_file():
        if sequence:
            raise ConfigError(f"source_path: {file} is not a file")
        return path.removeprefix("urfd:"), None
    if not sequence:
        names = {s.name for s in _all_sequences(file)}
        if len(names) != 1:
            raise ConfigError(
                f"source_path: {file} holds {len(names)} sequences; name one as {file}#<sequence>"
            )
        (sequence,) = names
    return sequence, file


def _all_sequences(file: str):
    from vigil.datasets import urfd

    try:
        return urfd.load(names=None, keypoints_file=file)
    except (OSError, ValueError, EOFError) as error:
        raise ConfigError(f"source_path: {file}: {error}") from None


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
        else:  # a URFD sequence (real data): fall-01, or FILE#fall-01 for a file in its format
            sequence, keypoints_file = _urfd_sequence(path)

            def make():
                return module.UrfdReplaySource(
                    sequence, speed=0, depth_dir=settings.depth_dir, keypoints_file=keypoints_file
                )
    elif kind == SourceKind.OPENPOSE:
        module = _module("openpose_dir", kind)

        def make():
            return module.OpenPoseDirSource(
                path, depth_dir=settings.depth_dir, depth_scale_mm=settings.depth_scale_mm
            )
    elif kind == SourceKind.ROSBAG:
        module = _module("rosbag", kind)

        def make():
            return module.RosbagSource(
                path,
                rgb_topic=settings.rgb_topic,
                depth_topic=settings.depth_topic,
                info_topic=settings.camera_info_topic,
                tolerance_s=settings.depth_tolerance_s,
                camera_height_m=settings.camera_height_m,
                camera_pitch_deg=settings.camera_pitch_deg,
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
            source = make()
            fps = getattr(source, "fps", None)
            yield TransportPlan(
                source,
                patient=settings.patient,
                location=settings.location,
                fps=float(fps) if fps else None,
            )
            if not settings.loop:
                return

    return plans()
