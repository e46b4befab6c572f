from fastapi import APIRouter, HTTPException, Query, status
from pydantic import BaseModel, ConfigDict
from sqlalchemy import func, select

from backend.deps import MAX_DB_INT, CurrentUser, SessionDep
from backend.models.taxonomy import TaxonomyLabel
from vigil.classes import Decision

router = APIRouter(prefix="/api", tags=["system"])


@router.get("/health")
def health() -> dict[str, str]:
    return {"status": "ok"}


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
    if version is None:
        version = session.scalar(select(func.max(TaxonomyLabel.version)))
    labels = session.scalars(
        select(TaxonomyLabel)
        .where(TaxonomyLabel.version == version)
        .order_by(TaxonomyLabel.position)
    ).all()
    if not labels:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"taxonomy version {version} not found")
    return TaxonomyOut(version=version, labels=[TaxonomyLabelOut.model_validate(x) for x in labels])
