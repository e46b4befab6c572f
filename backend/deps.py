"""FastAPI dependencies: database session, settings, the current user and the permission check."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import Depends, HTTPException, Path, Request, status
from sqlalchemy.orm import Session

from backend import unit_of_work
from backend.accounts import queries as account_queries
from backend.models._types import MAX_DB_INT  # the routers import it from here too
from backend.models.users import User
from backend.permissions import PERMISSIONS
from backend.security import SessionClaims, read_access_claims
from backend.settings import Settings
from backend.unit_of_work import UnitOfWork

SESSION_COOKIE = "vigil_session"


def get_settings(request: Request) -> Settings:
    return request.app.state.services.settings


async def get_unit(request: Request) -> AsyncIterator[UnitOfWork]:
    """The request's unit of work: committed when the endpoint returns without error, then its
    after-commit effects run (alarms pushed, assignments sent, sockets closed)."""
    services = request.app.state.services  # backend.services.Services
    async with unit_of_work.in_event_loop(services.session_factory, services.effects) as unit:
        yield unit


async def get_session(unit: UnitDep) -> Session:
    return unit.session


#: A path id that fits an INTEGER column (MAX_DB_INT, re-exported for the routers).
DbId = Annotated[int, Path(ge=1, le=MAX_DB_INT)]

SettingsDep = Annotated[Settings, Depends(get_settings)]
# scope="function": the commit happens when the endpoint returns, BEFORE the response is sent
# (with the default request scope a client could get 201 for a row that then fails to commit).
UnitDep = Annotated[UnitOfWork, Depends(get_unit, scope="function")]
SessionDep = Annotated[Session, Depends(get_session, scope="function")]


def bearer_token(request: Request) -> str | None:
    header = request.headers.get("authorization", "")
    scheme, _, value = header.partition(" ")
    if scheme.lower() == "bearer" and value:
        return value
    return request.cookies.get(SESSION_COOKIE)


def session_from_token(
    session: Session, settings: Settings, token: str | None
) -> tuple[User, SessionClaims] | None:
    """The user and claims of a token that is validly signed, unexpired, not revoked (logout)
    and whose user is still active (deactivation); None otherwise."""
    if not token:
        return None
    claims = read_access_claims(settings.secret_key, token)
    if claims is None or account_queries.is_revoked(session, claims.jti):
        return None
    user = session.get(User, claims.user_id)
    return (user, claims) if user is not None and user.active else None


def user_from_token(session: Session, settings: Settings, token: str | None) -> User | None:
    found = session_from_token(session, settings, token)
    return found[0] if found else None


def get_current_user(request: Request, session: SessionDep, settings: SettingsDep) -> User:
    found = session_from_token(session, settings, bearer_token(request))
    if found is None:
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "not signed in or session expired",
            headers={"WWW-Authenticate": "Bearer"},
        )
    user, request.state.session_claims = found
    route = request.scope.get("route")
    roles = PERMISSIONS.get((request.method, getattr(route, "path", "")))
    if roles is None:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "route has no permission entry")
    if roles and user.role not in roles:
        raise HTTPException(
            status.HTTP_403_FORBIDDEN,
            f"role {user.role} may not {request.method} {route.path}",
        )
    return user


CurrentUser = Annotated[User, Depends(get_current_user)]
