"""An optional lock around a benchmark's timed phases.

Benchmarks that share a machine (engineers' jobs, other benchmarks) time each other. When
`VIGIL_BENCH_LOCK` names a file, `timed_phase()` holds an exclusive `flock` on it while a
phase is timed, so untimed work (loading a history, training) can overlap other jobs while the
measurements themselves do not. `flock /same/file make bench-x` takes the same lock.
"""

from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def timed_phase(name: str) -> Iterator[float]:
    """Yields the seconds spent waiting for the lock (0 without a lock file)."""
    path = os.environ.get("VIGIL_BENCH_LOCK")
    if not path:
        yield 0.0
        return
    with open(path, "a") as handle:
        started = time.perf_counter()
        print(f"{name}: waiting for the benchmark lock {path}", flush=True)
        fcntl.flock(handle, fcntl.LOCK_EX)
        waited = time.perf_counter() - started
        print(f"{name}: lock held after {waited:.0f} s", flush=True)
        try:
            yield waited
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
