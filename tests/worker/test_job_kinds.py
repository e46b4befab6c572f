"""A job kind is declared in three places (docs/architecture.md, "A new job kind"): the
`JobKind` enum, its parameters in `backend.jobs.params.PARAMS` and its handler in
`worker.jobs.HANDLERS`; none may miss a kind."""

from __future__ import annotations

from backend.jobs.params import PARAMS
from backend.models.jobs import JobKind
from worker.jobs import HANDLERS


def test_every_job_kind_has_parameters_and_a_handler():
    assert set(PARAMS) == set(JobKind)
    assert set(HANDLERS) == set(JobKind)
