"""Account queries: users by name, revoked sessions."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from backend.models.users import RevokedSession, User


def user_by_username(session: Session, username: str) -> User | None:
    return session.scalars(select(User).where(User.username == username)).first()


def all_users(session: Session) -> list[User]:
    return list(session.scalars(select(User).order_by(User.id)))


def is_revoked(session: Session, jti: str) -> bool:
    return session.get(RevokedSession, jti) is not None


def delete_expired_revocations(session: Session, now: datetime) -> None:
    session.execute(delete(RevokedSession).where(RevokedSession.expires_at < now))
