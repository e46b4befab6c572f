"""Bounded password hashing: at most `concurrency` argon2 verifications run at once, in this
gate's own worker threads, so a login flood cannot take the CPU (two cores) from robot ingest.

argon2 verifies with the parallelism stored in the hash (4 lanes: 4 threads by default), so
even one verification can fill both cores for a few hundred ms. The gate's threads therefore
run at a lower scheduling priority (`nice`, inherited by argon2's lane threads): when ingest
needs the CPU it gets it, and hashing takes what is left.

A login waits at most `wait_s` for a slot; beyond `queue_max` waiting logins, or after the
wait, it is refused (the router answers 503 with Retry-After)."""

from __future__ import annotations

import asyncio
import logging
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

log = logging.getLogger(__name__)

T = TypeVar("T")


class HashingBusy(Exception):
    """No verification slot in time: the client should retry after a moment."""


def _lower_priority(nice: int) -> None:
    if nice <= 0 or not hasattr(os, "setpriority"):
        return
    tid = threading.get_native_id()
    try:
        current = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(19, current + nice))
    except OSError as error:  # not allowed here: hashing keeps the normal priority
        log.warning("could not lower the login hashing priority: %s", error)


class HashingGate:
    def __init__(self, concurrency: int, wait_s: float, queue_max: int, nice: int = 0) -> None:
        self._slots = asyncio.Semaphore(concurrency)
        self._wait_s = wait_s
        self._queue_max = queue_max
        self._waiting = 0
        self._executor = ThreadPoolExecutor(
            max_workers=concurrency,
            thread_name_prefix="vigil-login-hash",
            initializer=_lower_priority,
            initargs=(nice,),
        )

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
            return await asyncio.get_running_loop().run_in_executor(self._executor, function)
        finally:
            self._slots.release()

    def close(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
