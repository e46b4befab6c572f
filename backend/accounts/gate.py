"""Bounded password hashing: at most `concurrency` argon2 verifications run at once, each in a
worker thread, so a login flood cannot take the CPU (two cores) from robot ingest. A login
waits at most `wait_s` for a slot; beyond `queue_max` waiting logins, or after the wait, it is
refused (the router answers 503 with Retry-After)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import TypeVar

from starlette.concurrency import run_in_threadpool

T = TypeVar("T")


class HashingBusy(Exception):
    """No verification slot in time: the client should retry after a moment."""


class HashingGate:
    def __init__(self, concurrency: int, wait_s: float, queue_max: int) -> None:
        self._slots = asyncio.Semaphore(concurrency)
        self._wait_s = wait_s
        self._queue_max = queue_max
        self._waiting = 0

    @property
    def waiting(self) -> int:
        return self._waiting

    async def run(self, function: Callable[[], T]) -> T:
        if self._slots.locked() and self._waiting >= self._queue_max:
            raise HashingBusy("too many sign-ins at once")
        self._waiting += 1
        try:
            async with asyncio.timeout(self._wait_s):
                await self._slots.acquire()
        except TimeoutError:
            raise HashingBusy("too many sign-ins at once") from None
        finally:
            self._waiting -= 1
        try:
            return await run_in_threadpool(function)
        finally:
            self._slots.release()
