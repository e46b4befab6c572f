from fastapi import APIRouter, HTTPException, status
from pydantic import BaseModel, Field

from backend.accounts import queries, service
from backend.api.auth import UserOut
from backend.deps import CurrentUser, DbId, SessionDep
from backend.models.users import Role, User
from backend.security import hash_password
from backend.services import ServicesDep
from backend.unit_of_work import after_commit
from vigil.protocol import CLOSE_UNAUTHORIZED

router = APIRouter(prefix="/api", tags=["system"])


class UserIn(BaseModel):
    username: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    password: str = Field(min_length=8, max_length=256)
    role: Role
    ward: str | None = Field(default=None, max_length=64)
    display_name: str = Field(default="", max_length=128)


@router.get("/users")
def list_users(session: SessionDep, user: CurrentUser) -> list[UserOut]:
    return [UserOut.model_validate(u) for u in queries.all_users(session)]


@router.post("/users", status_code=status.HTTP_201_CREATED)
def create_user(body: UserIn, session: SessionDep, user: CurrentUser) -> UserOut:
    if queries.user_by_username(session, body.username):
        raise HTTPException(status.HTTP_409_CONFLICT, f"user {body.username} already exists")
    new = User(
        username=body.username,
        password_hash=hash_password(body.password),
        role=body.role,
        ward=body.ward,
        display_name=body.display_name or body.username,
    )
    session.add(new)
    session.flush()
    return UserOut.model_validate(new)


def _set_active(
    services: ServicesDep, session: SessionDep, actor: User, user_id: int, active: bool
) -> UserOut:
    try:
        target = service.set_active(session, actor, user_id, active)
    except service.AccountError as error:
        raise HTTPException(error.status_code, str(error)) from None
    if not active:  # once committed: a reconnect must already be refused
        hub = services.hub
        after_commit(
            session, lambda: hub.close_user(user_id, CLOSE_UNAUTHORIZED, "account deactivated")
        )
    return UserOut.model_validate(target)


@router.post("/users/{user_id}/deactivate")
def deactivate_user(
    user_id: DbId, session: SessionDep, user: CurrentUser, services: ServicesDep
) -> UserOut:
    """Every session of the user stops working at once, open browser sockets included (4401).
    The user's data stays; reactivating lets them sign in again."""
    return _set_active(services, session, user, user_id, False)


@router.post("/users/{user_id}/reactivate")
def reactivate_user(
    user_id: DbId, session: SessionDep, user: CurrentUser, services: ServicesDep
) -> UserOut:
    return _set_active(services, session, user, user_id, True)
