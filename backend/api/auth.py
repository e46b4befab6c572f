from functools import partial

from fastapi import APIRouter, HTTPException, Request, Response, status
from pydantic import BaseModel, ConfigDict, Field
from sqlalchemy.orm import Session, sessionmaker

from backend.accounts import queries, service
from backend.accounts.gate import HashingBusy
from backend.accounts.throttle import retry_after_header
from backend.db import transaction
from backend.deps import SESSION_COOKIE, CurrentUser, SessionDep
from backend.models.users import Role, User
from backend.security import create_access_token, needs_rehash
from backend.services import ServicesDep
from backend.unit_of_work import after_commit
from vigil.protocol import CLOSE_UNAUTHORIZED

router = APIRouter(prefix="/api/auth", tags=["auth"])


class LoginIn(BaseModel):
    username: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=256)


class UserOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    username: str
    display_name: str
    role: Role
    ward: str | None
    active: bool = True


class TokenOut(BaseModel):
    access_token: str
    token_type: str = "bearer"
    user: UserOut


class ErrorOut(BaseModel):
    detail: str


def _authenticate(factory: sessionmaker[Session], username: str, password: str) -> User | None:
    """Runs in the hashing gate's thread. No database connection is held while hashing (a
    flood would otherwise empty the pool); a rehash, if needed, is its own short commit."""
    with factory() as session:
        user = queries.user_by_username(session, username)
    if not service.password_matches(user, password):
        return None
    if needs_rehash(user.password_hash):
        with transaction(factory) as session:
            service.upgrade_password_hash(session, user.id, password)
    return user


@router.post(
    "/login",
    responses={
        401: {"model": ErrorOut, "description": "wrong username or password"},
        429: {"model": ErrorOut, "description": "locked out after failures (Retry-After)"},
        503: {"model": ErrorOut, "description": "too many sign-ins at once (Retry-After)"},
    },
)
async def login(
    body: LoginIn, request: Request, response: Response, state: ServicesDep
) -> TokenOut:
    settings = state.settings
    client = request.client.host if request.client else "unknown"
    wait = state.login_throttle.retry_after(body.username, client)
    if wait > 0:
        raise HTTPException(
            status.HTTP_429_TOO_MANY_REQUESTS,
            f"too many failed sign-ins: try again in {retry_after_header(wait)} s",
            headers={"Retry-After": retry_after_header(wait)},
        )
    try:
        user = await state.login_gate.run(
            partial(_authenticate, state.session_factory, body.username, body.password)
        )
    except HashingBusy as error:
        raise HTTPException(
            status.HTTP_503_SERVICE_UNAVAILABLE,
            f"{error}: try again in a moment",
            headers={"Retry-After": "1"},
        ) from None
    if user is None:
        state.login_throttle.failed(body.username, client)
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "wrong username or password")
    state.login_throttle.succeeded(body.username)
    token = create_access_token(settings.secret_key, user.id, settings.access_token_minutes)
    response.set_cookie(
        SESSION_COOKIE,
        token,
        max_age=settings.access_token_minutes * 60,
        httponly=True,
        samesite="strict",
        secure=settings.cookie_secure,
    )
    return TokenOut(access_token=token, user=UserOut.model_validate(user))


@router.post("/logout", status_code=status.HTTP_204_NO_CONTENT)
def logout(
    user: CurrentUser,
    session: SessionDep,
    request: Request,
    response: Response,
    services: ServicesDep,
) -> None:
    """End this session on the server: its token is refused from now on (other sessions of
    the user stay), and the browser sockets opened with it are closed (4401)."""
    claims = request.state.session_claims
    service.revoke_session(session, claims)
    hub = services.hub  # once committed: a reconnect must already be refused
    after_commit(session, lambda: hub.close_session(claims.jti, CLOSE_UNAUTHORIZED, "signed out"))
    response.delete_cookie(SESSION_COOKIE)


@router.get("/me")
def me(user: CurrentUser, request: Request) -> UserOut:
    return UserOut.model_validate(user)
