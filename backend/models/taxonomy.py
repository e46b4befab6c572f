from datetime import datetime

from sqlalchemy import ForeignKey, String, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from backend.models._types import UTCDateTime, utcnow
from backend.models.base import Base
from vigil.classes import Decision


class TaxonomyVersion(Base):
    __tablename__ = "taxonomy_versions"

    version: Mapped[int] = mapped_column(primary_key=True, autoincrement=False)
    comment: Mapped[str] = mapped_column(String(512), default="")
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, default=utcnow)


class TaxonomyLabel(Base):
    __tablename__ = "taxonomy_labels"
    __table_args__ = (UniqueConstraint("version", "key", name="uq_taxonomy_label"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    version: Mapped[int] = mapped_column(ForeignKey("taxonomy_versions.version"))
    position: Mapped[int] = mapped_column()
    key: Mapped[str] = mapped_column(String(64))
    name: Mapped[str] = mapped_column(String(128))
    walking: Mapped[Decision] = mapped_column(String(16))
    wheelchair: Mapped[Decision] = mapped_column(String(16))
    combined: Mapped[Decision] = mapped_column(String(16))
