"""The database copy of the taxonomy, in the taxonomy's one shape (`vigil.taxonomy.Taxonomy`)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.labelling.errors import LabellingError
from backend.models.taxonomy import TaxonomyLabel
from vigil.classes import Decision
from vigil.taxonomy import FineLabel, Taxonomy


def load_taxonomy(session: Session, version: int | None = None) -> Taxonomy:
    """Version `version` (default: the newest); LabellingError if it does not exist."""
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
    return Taxonomy(
        version=version,
        labels=tuple(
            FineLabel(
                r.key, r.name, Decision(r.walking), Decision(r.wheelchair), Decision(r.combined)
            )
            for r in rows
        ),
    )


def taxonomy_versions(session: Session) -> list[int]:
    return list(session.scalars(select(TaxonomyLabel.version).distinct()))


def require(taxonomy: Taxonomy, key: str) -> FineLabel:
    """The fine label `key`; a LabellingError naming the field where the taxonomy has none."""
    label = taxonomy.get(key)
    if label is None:
        raise LabellingError(
            f"label_key: {key!r} is not a fine label of taxonomy v{taxonomy.version}"
        )
    return label
