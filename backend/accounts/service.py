"""Sign-in, logout and (de)activation. Services never commit: the request's unit of work does."""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy.orm import Session

from backend.accounts import queries
from backend.models._types import utcnow
from backend.models.users import RevokedSession, User
from backend.security import (
    SessionClaims,
    hash_password,
    needs_rehash,
    verify_password_or_dummy,
)


class AccountError(Exception):
    """A refused account change; `status_code` is the HTTP status it maps to."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status_code = status


def password_matches(user: User | None, password: str) -> bool:
    """Whether `user` exists, is active and has this password. Unknown and inactive users cost
    one argon2 verification too, so the timing tells nothing about who exists. No database
    access: the caller holds no connection during the (slow) verification."""
    ok = verify_password_or_dummy(user.password_hash if user else None, password)
    return ok and user is not None and user.active


def upgrade_password_hash(session: Session, user_id: int, password: str) -> None:
    """Rehash a password whose stored hash was made with older parameters (e.g. 4 lanes)."""
    user = session.get(User, user_id)
    if user is not None and needs_rehash(user.password_hash):
        user.password_hash = hash_password(password)


def revoke_session(session: Session, claims: SessionClaims) -> None:
    """Refuse this session's token from now on (logout); forget revocations that expired."""
    now = utcnow()
    queries.delete_expired_revocations(session, now)
    if not queries.is_revoked(session, claims.jti):
        session.add(
            RevokedSession(
                jti=claims.jti,
                user_id=claims.user_id,
                expires_at=datetime.fromtimestamp(claims.expires_at, UTC),
                revoked_at=now,
            )
        )


def set_active(session: Session, actor: User, user_id: int, active: bool) -> User:
    """Deactivate (every session of the user stops working: tokens are checked against
    `active` on each request) or reactivate a user. An admin cannot deactivate themself (the
    last way back in would be the database)."""
    user = session.get(User, user_id)
    if user is None:
        raise AccountError(404, f"user {user_id} not found")
    if not active and user.id == actor.id:
        raise AccountError(409, "you cannot deactivate your own account")
    user.active = active
    return user
