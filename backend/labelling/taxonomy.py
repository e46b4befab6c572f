"""The database copy of the taxonomy, as the labelling services need it."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.labelling.errors import LabellingError
from backend.models.taxonomy import TaxonomyLabel
from vigil.classes import Decision, TransportMode


@dataclass(frozen=True, slots=True)
class LabelClasses:
    key: str
    name: str
    walking: Decision
    wheelchair: Decision
    combined: Decision

    def decision(self, mode: TransportMode | str) -> Decision:
        return Decision(getattr(self, TransportMode(mode).value))


@dataclass(frozen=True, slots=True)
class DbTaxonomy:
    version: int
    labels: dict[str, LabelClasses]

    def require(self, key: str) -> LabelClasses:
        if key not in self.labels:
            raise LabellingError(
                f"label_key: {key!r} is not a fine label of taxonomy v{self.version}"
            )
        return self.labels[key]


def load_taxonomy(session: Session, version: int | None = None) -> DbTaxonomy:
    if version is None:
        version = session.scalar(select(func.max(TaxonomyLabel.version)))
        if version is None:
            raise RuntimeError("no taxonomy in the database; run the migrations")
    rows = session.scalars(
        select(TaxonomyLabel)
        .where(TaxonomyLabel.version == version)
        .order_by(TaxonomyLabel.position)
    ).all()
    if not rows:
        raise LabellingError(f"taxonomy_version: {version} does not exist")
    return DbTaxonomy(
        version=version,
        labels={
            r.key: LabelClasses(r.key, r.name, r.walking, r.wheelchair, r.combined) for r in rows
        },
    )
