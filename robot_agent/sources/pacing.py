"""Replaying recorded frames in real time, faster, or as fast as possible."""

from __future__ import annotations

import time
from collections.abc import Callable


class Pacer:
    """Sleeps so that the frame stamped ``timestamp`` (seconds from the first frame) is released
    at ``timestamp / speed`` seconds after the first; speed 0 (or inf) never sleeps."""

    def __init__(
        self,
        speed: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if speed < 0 or speed != speed:
            raise ValueError(f"speed must be >= 0 (0: as fast as possible), got {speed}")
        self.speed = speed
        self._clock = clock
        self._sleep = sleep
        self._start: float | None = None
        self._first_ts = 0.0

    @property
    def realtime(self) -> bool:
        return 0 < self.speed < float("inf")

    def wait(self, timestamp: float) -> None:
        if not self.realtime:
            return
        if self._start is None:
            self._start, self._first_ts = self._clock(), timestamp
            return
        due = self._start + (timestamp - self._first_ts) / self.speed
        delay = due - self._clock()
        if delay > 0:
            self._sleep(delay)
