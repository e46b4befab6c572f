"""The worker loop: claim a job, run its handler with a JobContext, record the outcome.

A heartbeat thread keeps the claim alive (and flushes progress and log lines) while the handler
computes, so a long model fit is not mistaken for a dead worker; the handler itself checks for
cancellation whenever it reports progress.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field

from sqlalchemy.orm import Session, sessionmaker

from backend.db import make_engine, make_session_factory, transaction
from backend.models.jobs import JobStatus
from worker import queue
from worker.settings import WorkerSettings

log = logging.getLogger("vigil.worker")


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


Handler = Callable[[JobContext], dict]


class Worker:
    def __init__(
        self,
        settings: WorkerSettings,
        factory: sessionmaker[Session] | None = None,
        handlers: dict[str, Handler] | None = None,
        sweeps: list[Callable[[sessionmaker[Session], WorkerSettings], None]] | None = None,
    ) -> None:
        from worker.jobs import HANDLERS
        from worker.sweeps import SWEEPS

        self.settings = settings
        self.worker_id = settings.worker_id or f"{socket.gethostname()}:{os.getpid()}"
        self._engine = None
        if factory is None:
            self._engine = make_engine(settings.database_url)
            factory = make_session_factory(self._engine)
        self.factory = factory
        self.handlers = handlers if handlers is not None else HANDLERS
        self.sweeps = sweeps if sweeps is not None else SWEEPS
        self._stop = threading.Event()
        self._last_sweep = 0.0

    def stop(self) -> None:
        self._stop.set()

    def run_once(self) -> int | None:
        """Claim and run one job; returns its id, or None when the queue was empty."""
        claim = queue.claim(
            self.factory,
            self.worker_id,
            self.settings.worker_stale_after_s,
            self.settings.worker_max_attempts,
            kinds=list(self.handlers),
        )
        if claim is None:
            return None
        context = JobContext(
            claim.id, claim.params, claim.created_by_id, self.factory, self.settings, self.worker_id
        )
        log.info("job %s (%s) claimed, attempt %s", claim.id, claim.kind, claim.attempts)
        beating = threading.Event()
        heartbeat = threading.Thread(target=self._heartbeat, args=(context, beating), daemon=True)
        heartbeat.start()
        try:
            result = self.handlers[claim.kind](context)
        except JobCancelled as stop:
            status, message, result = JobStatus.CANCELLED, str(stop), None
        except Exception as error:  # a failed job is recorded, the worker keeps going
            log.exception("job %s failed", claim.id)
            context.log(traceback.format_exc(limit=8))
            status, message, result = JobStatus.FAILED, f"{type(error).__name__}: {error}", None
        else:
            status, message = JobStatus.SUCCEEDED, (result or {}).get("summary", "done")
        finally:
            beating.set()
            heartbeat.join()
        queue.finish(
            self.factory, claim.id, self.worker_id, status, message, result, context.take_lines()
        )
        log.info("job %s %s: %s", claim.id, status, message)
        return claim.id

    def _heartbeat(self, context: JobContext, done: threading.Event) -> None:
        while not done.wait(self.settings.worker_heartbeat_s):
            try:
                context.flush()
            except Exception:  # the database may blip; the next beat retries
                log.exception("heartbeat of job %s failed", context.job_id)

    def sweep(self) -> None:
        now = time.monotonic()
        if now - self._last_sweep < self.settings.worker_sweep_s:
            return
        self._last_sweep = now
        for run_sweep in self.sweeps:
            try:
                run_sweep(self.factory, self.settings)
            except Exception:
                log.exception("sweep %s failed", getattr(run_sweep, "__name__", run_sweep))

    def run_forever(self) -> None:
        log.info("worker %s polling the job queue", self.worker_id)
        while not self._stop.is_set():
            self.sweep()
            if self.run_once() is None:
                self._stop.wait(self.settings.worker_poll_s)
        if self._engine is not None:
            self._engine.dispose()
