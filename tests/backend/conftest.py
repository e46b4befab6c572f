from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from fastapi.testclient import TestClient

from backend.db import make_engine, make_session_factory, transaction
from backend.main import create_app
from backend.models.robots import Robot
from backend.models.users import Role, User
from backend.security import create_access_token, hash_robot_token
from backend.settings import Settings
from tests.support.passwords import password_hash

PASSWORD = "correct horse battery"
ROBOT_TOKEN = "robot-secret-token-for-tests"
# The secret of backends started as subprocesses (uvicorn), so tests can mint tokens for them.
SUBPROCESS_SECRET = "subprocess-backend-secret"


@pytest.fixture
def settings(database_url: str, tmp_path) -> Settings:
    return Settings(
        database_url=database_url,
        frontend_dir=tmp_path / "no-frontend",
        model_store_dir=tmp_path / "models",
        secret_key="test-secret",
    )


@pytest.fixture
def session_factory(settings: Settings):
    engine = make_engine(settings.database_url)
    yield make_session_factory(engine)
    engine.dispose()


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    with TestClient(create_app(settings)) as test_client:
        yield test_client


@dataclass
class Account:
    username: str
    role: Role
    ward: str | None
    token: str = ""

    @property
    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"}


@pytest.fixture
def make_account(client: TestClient, session_factory):
    def make(role: Role, ward: str | None = "ward-a", username: str | None = None) -> Account:
        username = username or f"{role.value}-{ward or 'all'}"
        with transaction(session_factory) as session:
            session.add(
                User(username=username, password_hash=password_hash(PASSWORD), role=role, ward=ward)
            )
        response = client.post("/api/auth/login", json={"username": username, "password": PASSWORD})
        assert response.status_code == 200, response.text
        client.cookies.clear()
        return Account(username, role, ward, response.json()["access_token"])

    return make


@pytest.fixture
def robot(session_factory) -> str:
    with transaction(session_factory) as session:
        session.add(
            Robot(id="robot-a", name="A", ward="ward-a", token_hash=hash_robot_token(ROBOT_TOKEN))
        )
    return "robot-a"


@pytest.fixture
def nurse_token(session_factory) -> str:
    """A ward-a nurse's access token, valid on a subprocess backend (`SUBPROCESS_SECRET`)."""
    with transaction(session_factory) as session:
        user = User(
            username="nurse",
            password_hash=password_hash("nurse-password"),
            role=Role.NURSE,
            ward="ward-a",
        )
        session.add(user)
        session.flush()
        user_id = user.id
    return create_access_token(SUBPROCESS_SECRET, user_id, 60)
