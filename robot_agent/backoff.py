"""Reconnect delays: exponential backoff with jitter, reset after a good connection."""

from __future__ import annotations

import random


class Backoff:
    """Delay n (from 0) is ``min(maximum, initial * factor**n)`` scaled by a random factor in
    ``[1 - jitter, 1]``, so that a fleet cut off together does not reconnect in lock-step."""

    def __init__(
        self,
        initial: float = 0.5,
        maximum: float = 30.0,
        factor: float = 2.0,
        jitter: float = 0.5,
        rng: random.Random | None = None,
    ) -> None:
        if initial <= 0 or maximum < initial or factor < 1 or not 0 <= jitter < 1:
            raise ValueError("need 0 < initial <= maximum, factor >= 1 and 0 <= jitter < 1")
        self.initial, self.maximum, self.factor, self.jitter = initial, maximum, factor, jitter
        self._rng = rng or random.Random()
        self.attempt = 0

    def ceiling(self) -> float:
        """The delay before jitter for the current attempt."""
        return min(self.maximum, self.initial * self.factor ** min(self.attempt, 64))

    def next_delay(self) -> float:
        delay = self.ceiling() * (1 - self.jitter * self._rng.random())
        self.attempt += 1
        return delay

    def reset(self) -> None:
        self.attempt = 0
