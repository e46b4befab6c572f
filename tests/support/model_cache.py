"""Test models trained once for both of `make test`'s runs.

The session fixtures that train a small model on URFD (about 20 s of CPU each) would train it
in the SQLite run and again in the PostgreSQL run. With VIGIL_TEST_MODEL_CACHE naming a
directory both runs share (the Makefile makes one per `make test`), the first run to need a
model trains it there under a file lock and the other waits for it and reads the same files.
Without the variable each run trains its own, as before."""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Callable
from pathlib import Path


def trained_once(name: str, train: Callable[[Path], None], own_dir: Path) -> Path:
    """The directory `train(directory)` filled with model `name`: the shared cache's copy when
    there is a cache (trained by whichever run came first), else `own_dir`, trained here."""
    cache = os.environ.get("VIGIL_TEST_MODEL_CACHE")
    if not cache:
        train(own_dir)
        return own_dir
    root = Path(cache)
    root.mkdir(parents=True, exist_ok=True)
    target, complete = root / name, root / f"{name}.complete"
    with (root / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not complete.exists():
            shutil.rmtree(target, ignore_errors=True)  # a run that died while training
            train(target)
            complete.touch()
    return target
