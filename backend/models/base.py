"""The declarative base of every table (its own module: models import nothing else of the
backend, so the unit of work can name them without an import circle)."""

from sqlalchemy.orm import DeclarativeBase


class Base(DeclarativeBase):
    pass
