"""What every keypoint source yields: one Observation per camera frame.

The agent's pipeline is source -> patient tracking -> depth sampling -> classification ->
outbox; sources know nothing of the later steps.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol

from vigil.observation import Observation


class KeypointSource(Protocol):
    """An iterable of observations; `realtime` sources pace themselves at their frame rate."""

    name: str
    fps: float

    def __iter__(self) -> Iterator[Observation]: ...
