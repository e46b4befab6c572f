"""Grid search scale-out: the joblib backend GridSearchCV runs on (worker.training.detector).

On a Dask cluster through joblib's dask backend when a scheduler address is set
(VIGIL_DASK_SCHEDULER), else in local processes (VIGIL_GRID_N_JOBS) or in this process. Folds,
scoring and the operating point stay in worker.training: only where the tasks run changes.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from joblib import parallel_config


@dataclass
class GridBackend:
    scheduler: str | None = None
    n_jobs: int = 1

    @property
    def description(self) -> str:
        return f"dask cluster at {self.scheduler}" if self.scheduler else f"{self.n_jobs} local"

    @contextmanager
    def active(self) -> Iterator[None]:
        """Within this block, joblib (and so GridSearchCV with n_jobs=None) uses this backend."""
        if self.scheduler:
            from distributed import Client

            client = Client(self.scheduler, timeout="10s", set_as_default=False)
            with client, parallel_config(backend="dask", client=client, n_jobs=-1):
                yield
        elif self.n_jobs == 1:
            yield
        else:
            with parallel_config(backend="loky", n_jobs=self.n_jobs):
                yield
