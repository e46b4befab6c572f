"""Login lockout with exponential backoff, per user name and per client address.

After `free` wrong passwords, each further one locks the key for base * 2**(n - free) seconds
(capped). While a key is locked every attempt, even with the right password, is refused with
its Retry-After, and no password is verified (a locked attacker costs no argon2 time). A
successful sign-in clears the user name's record, not the client's (else signing in to one's
own account would reset a password-spraying client). Records are forgotten after `memory_s`
without a new failure, and the table is bounded (oldest records dropped first).

The records live in this process: with several backend replicas each keeps its own, so an
attacker spreading attempts over N replicas gets N times the attempts.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class _Record:
    failures: int = 0
    locked_until: float = 0.0
    last_failure: float = 0.0


@dataclass(frozen=True)
class Policy:
    free: int
    base_s: float
    max_s: float


class LoginThrottle:
    def __init__(
        self,
        user_policy: Policy,
        client_policy: Policy,
        memory_s: float,
        max_records: int = 100_000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._policies = {"user": user_policy, "client": client_policy}
        self._memory_s = memory_s
        self._max_records = max_records
        self._clock = clock
        self._records: OrderedDict[tuple[str, str], _Record] = OrderedDict()

    @staticmethod
    def _keys(username: str, client: str) -> tuple[tuple[str, str], ...]:
        return (("user", username.casefold()), ("client", client))

    def _record(self, key: tuple[str, str], now: float) -> _Record | None:
        record = self._records.get(key)
        if record is not None and now - record.last_failure > self._memory_s:
            del self._records[key]
            return None
        return record

    def retry_after(self, username: str, client: str) -> float:
        """Seconds until an attempt for this user from this client is allowed (0: now)."""
        now = self._clock()
        wait = 0.0
        for key in self._keys(username, client):
            record = self._record(key, now)
            if record is not None:
                wait = max(wait, record.locked_until - now)
        return max(0.0, wait)

    def failed(self, username: str, client: str) -> float:
        """Count a wrong password; returns the lockout it starts (0: none yet)."""
        now = self._clock()
        wait = 0.0
        for key in self._keys(username, client):
            record = self._record(key, now) or _Record()
            record.failures += 1
            record.last_failure = now
            policy = self._policies[key[0]]
            if record.failures >= policy.free:
                exponent = min(record.failures - policy.free, 30)
                lock = min(policy.max_s, policy.base_s * 2**exponent)
                record.locked_until = max(record.locked_until, now + lock)
                wait = max(wait, record.locked_until - now)
            self._records[key] = record
            self._records.move_to_end(key)
        while len(self._records) > self._max_records:
            self._records.popitem(last=False)
        return wait

    def succeeded(self, username: str) -> None:
        self._records.pop(("user", username.casefold()), None)


def retry_after_header(seconds: float) -> str:
    return str(max(1, math.ceil(seconds)))
