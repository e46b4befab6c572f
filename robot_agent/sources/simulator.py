"""GENERATED transports from vigil.synthetic as a camera source (demos and load)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

from robot_agent.sources import Observation
from vigil.synthetic import Locomotion, generate_transport


def simulated_transports(
    seed: int = 0,
    locomotions: Sequence[Locomotion | str] = (Locomotion.WALKING, Locomotion.ROLLATOR),
    duration_s: float = 30.0,
    n_people: int = 1,
    count: int | None = None,
) -> Iterator[tuple[Locomotion, Iterator[Observation]]]:
    """Endless (or ``count``) generated transports, each with at least one emergency event."""
    index = 0
    while count is None or index < count:
        locomotion = Locomotion(locomotions[index % len(locomotions)])
        transport = generate_transport(
            locomotion, seed=seed * 10_000 + index, duration_s=duration_s, n_people=n_people
        )
        yield locomotion, _observations(transport)
        index += 1


def _observations(transport) -> Iterator[Observation]:
    truth = transport.decisions()
    for t in range(transport.n_frames):
        yield Observation(
            timestamp=t / transport.fps,
            people=transport.detections(t),
            truth=truth[t],
            new_transport=t == 0,
            extra={"label": transport.labels[t], "generated": True},
        )
