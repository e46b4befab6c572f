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

from sqlalchemy.orm import Session, sessionmaker

from backend.db import make_engine, make_session_factory
from backend.jobs import queue
from backend.models.jobs import JobStatus
from backend.registry.sweeps import SWEEPS as REGISTRY_SWEEPS
from backend.registry.sweeps import Sweep
from backend.storage.sweeps import SWEEPS as STORAGE_SWEEPS
from worker.context import JobCancelled, JobContext
from worker.jobs import HANDLERS
from worker.settings import WorkerSettings

log = logging.getLogger("vigil.worker")


Handler = Callable[[JobContext], dict]


class Worker:
    def __init__(
        self,
        settings: WorkerSettings,
        factory: sessionmaker[Session] | None = None,
        handlers: dict[str, Handler] | None = None,
        sweeps: list[Sweep] | None = None,
    ) -> None:
        self.settings = settings
        self.worker_id = settings.worker_id or f"{socket.gethostname()}:{os.getpid()}"
        self._engine = None
        if factory is None:
            self._engine = make_engine(settings.database_url)
            factory = make_session_factory(self._engine)
        self.factory = factory
        self.handlers = handlers if handlers is not None else HANDLERS
        self.sweeps = sweeps if sweeps is not None else [*REGISTRY_SWEEPS, *STORAGE_SWEEPS]
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
