"""What a job handler sees (`JobContext`): its job, the database, settings and progress
reporting. Its own module so that the loop (`worker.runner`) and the handlers (`worker.jobs`)
both import it without importing each other."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from sqlalchemy.orm import Session, sessionmaker

from backend.db import transaction
from backend.jobs import queue
from worker.settings import WorkerSettings


class JobCancelled(Exception):
    pass


@dataclass
class JobContext:
    """What a handler sees: its job, the database, settings, and progress reporting."""

    job_id: int
    params: dict
    created_by_id: int | None
    factory: sessionmaker[Session]
    settings: WorkerSettings
    worker_id: str
    _progress: float = 0.0
    _message: str = ""
    _lines: list[str] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _cancelled: bool = False
    _lost: bool = False

    def read(self) -> Session:
        """A session that only reads (loading data, evaluating): it commits nothing."""
        return self.factory()

    def write(self):
        """A unit of work for a step whose writes the job needs before going on (re-importing
        archived frames to train on): it commits when the block ends."""
        return transaction(self.factory)

    def result(self):
        """The job's unit of work that stores its result: a job commits once (its progress goes
        in the queue's own short transactions, `flush`)."""
        return transaction(self.factory)

    def progress(self, fraction: float, message: str | None = None) -> None:
        """Report progress (0..1); raises JobCancelled when an engineer cancelled the job."""
        with self._lock:
            self._progress = fraction
            if message is not None:
                self._message = message
                self._lines.append(f"[{time.strftime('%H:%M:%S')}] {message}")
        self.flush()
        if self._cancelled or self._lost:
            raise JobCancelled("cancelled by request" if self._cancelled else "job taken over")

    def log(self, line: str) -> None:
        with self._lock:
            self._lines.append(f"[{time.strftime('%H:%M:%S')}] {line}")

    def take_lines(self) -> list[str]:
        with self._lock:
            lines, self._lines = self._lines, []
            return lines

    def flush(self) -> None:
        with self._lock:
            progress, message, lines = self._progress, self._message, self._lines
            self._lines = []
        cancel = queue.report(
            self.factory, self.job_id, self.worker_id, progress, message or None, lines
        )
        if cancel is None:
            self._lost = True
        elif cancel:
            self._cancelled = True
