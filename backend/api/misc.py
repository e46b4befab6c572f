from typing import Literal

from fastapi import APIRouter, HTTPException, Query, status
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from backend import health as health_checks
from backend.deps import MAX_DB_INT, CurrentUser, SessionDep
from backend.labelling.errors import LabellingError
from backend.labelling.taxonomy import load_taxonomy
from backend.services import Services, ServicesDep
from vigil.classes import Decision

router = APIRouter(prefix="/api", tags=["system"])


class LiveOut(BaseModel):
    status: Literal["ok"] = "ok"


class HealthOut(BaseModel):
    status: Literal["ok", "unavailable"]
    checks: dict[str, str] = Field(
        description='each dependency checked ("database", "redis" when configured): "ok" or why not'
    )
    detail: str | None = Field(default=None, description="why not ready")
    storage_stalled_s: float | None = Field(
        default=None,
        description="how long the frame writer's current write has been blocked, when it is "
        "longer than storage_stall_seconds (the nurse board shows a storage-stalled alarm)",
    )
    duties: dict | None = Field(
        default=None,
        description="whether this replica runs the alarm monitor and alarm distribution (one "
        "replica at a time): replica, leading, since, terms, last_error",
    )


@router.get("/health/live")
def live() -> LiveOut:
    """Liveness: the process answers (says nothing about the database)."""
    return LiveOut()


async def _ready(state: Services) -> JSONResponse:
    result = await health_checks.readiness(state.engine, state.bus, state.settings.health_timeout_s)
    writer = state.writer
    if writer is not None:
        blocked = writer.blocked_for()
        limit = state.settings.ready_storage_stall_s
        if blocked is not None and blocked > limit:
            reason = (
                f"stalled: a frame write has been blocked {blocked:.1f} s "
                f"(over ready_storage_stall_s = {limit:g} s)"
            )
            result = health_checks.Readiness(False, {**result.checks, "storage": reason})
    body = HealthOut(
        status="ok" if result.ready else "unavailable",
        checks=result.checks,
        detail=None if result.ready else result.reason,
        storage_stalled_s=writer.stalled_for() if writer is not None else None,
        duties=state.leadership.status() if state.leadership is not None else None,
    )
    code = status.HTTP_200_OK if result.ready else status.HTTP_503_SERVICE_UNAVAILABLE
    return JSONResponse(body.model_dump(mode="json"), status_code=code)


READY_RESPONSES = {200: {"model": HealthOut}, 503: {"model": HealthOut, "description": "not ready"}}


@router.get("/health/ready", response_model=HealthOut, responses=READY_RESPONSES)
async def ready(services: ServicesDep) -> JSONResponse:
    """Readiness: 200 when the database (and Redis when configured) answers within
    health_timeout_s and no frame write has been blocked longer than ready_storage_stall_s,
    else 503 with the reason."""
    return await _ready(services)


@router.get("/health", response_model=HealthOut, responses=READY_RESPONSES)
async def health(services: ServicesDep) -> JSONResponse:
    """Same as /api/health/ready (readiness); /api/health/live is liveness."""
    return await _ready(services)


class TaxonomyLabelOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    key: str
    name: str
    walking: Decision
    wheelchair: Decision
    combined: Decision


class TaxonomyOut(BaseModel):
    version: int
    labels: list[TaxonomyLabelOut]


@router.get("/taxonomy")
def taxonomy(
    session: SessionDep,
    user: CurrentUser,
    version: int | None = Query(default=None, ge=1, le=MAX_DB_INT),
) -> TaxonomyOut:
    try:
        found = load_taxonomy(session, version)
    except LabellingError:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND, f"taxonomy version {version} not found"
        ) from None
    return TaxonomyOut(
        version=found.version, labels=[TaxonomyLabelOut.model_validate(x) for x in found.labels]
    )
