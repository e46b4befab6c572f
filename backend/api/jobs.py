"""Worker jobs: queue, list with live progress, detail with log, cancel. The queue's state
rules live in backend.jobs.queue (a light module: no training code is imported here)."""

from fastapi import APIRouter, HTTPException, status

from backend.deps import CurrentUser, SessionDep, SettingsDep
from backend.jobs import params as job_params
from backend.jobs import queries, queue
from backend.jobs.schemas import JobDetail, JobIn, JobOut
from backend.models.jobs import Job, JobStatus

router = APIRouter(prefix="/api", tags=["jobs"])


def _job(session, job_id: int) -> Job:
    job = queries.job_by_id(session, job_id)
    if job is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"job {job_id} not found")
    return job


@router.get("/jobs")
def list_jobs(
    session: SessionDep, user: CurrentUser, status: JobStatus | None = None, limit: int = 100
) -> list[JobOut]:
    return [JobOut.model_validate(j) for j in queries.list_jobs(session, status, limit)]


@router.post("/jobs", status_code=status.HTTP_201_CREATED)
def create_job(
    body: JobIn, session: SessionDep, user: CurrentUser, settings: SettingsDep
) -> JobOut:
    """Queue a job; parameters are checked here (422 naming the field) and again by the worker.
    A register job reads only from the model store (settings.model_store_dir)."""
    try:
        params = job_params.validate(body.kind, body.params, settings.model_store_dir)
    except ValueError as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(error)) from None
    job = queue.enqueue(session, body.kind, params, user.id)
    session.flush()
    session.refresh(job)
    return JobOut.model_validate(job)


@router.get("/jobs/{job_id}")
def get_job(job_id: int, session: SessionDep, user: CurrentUser) -> JobDetail:
    return JobDetail.model_validate(_job(session, job_id))


@router.post("/jobs/{job_id}/cancel")
def cancel_job(job_id: int, session: SessionDep, user: CurrentUser) -> JobOut:
    job = _job(session, job_id)
    queue.request_cancel(session, job)  # a finished job: 409 (IllegalTransition)
    session.flush()
    return JobOut.model_validate(job)
