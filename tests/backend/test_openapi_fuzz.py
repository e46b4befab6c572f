"""Schemathesis against the OpenAPI of the real backend (uvicorn subprocess): generated
requests to every operation, as an admin (who may call every route), never get a 5xx."""

from __future__ import annotations

import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings

from backend.db import transaction
from backend.models import Role, User
from backend.process import BackendProcess
from backend.security import create_access_token, hash_password
from tests.backend.test_reliability import SECRET, backend_env  # noqa: F401  (fixture)

EXAMPLES_PER_OPERATION = 12


@pytest.mark.timeout(180)
def test_generated_requests_never_get_a_server_error(
    backend_env,  # noqa: F811
    robot,
    session_factory,
    tmp_path,
):
    with transaction(session_factory) as session:
        admin = User(username="admin", password_hash=hash_password("admin-password"),
                     role=Role.ADMIN)  # fmt: skip
        session.add(admin)
        session.flush()
        headers = {"Authorization": f"Bearer {create_access_token(SECRET, admin.id, 60)}"}

    failures: list[str] = []
    with BackendProcess(backend_env, log_path=tmp_path / "backend.log") as server:
        schema = schemathesis.openapi.from_url(f"{server.http}/openapi.json")
        operations = [result.ok() for result in schema.get_all_operations()]
        assert len(operations) >= 20
        for operation in operations:
            if operation.path.endswith(("/logout", "/token")) and operation.method != "get":
                continue  # would sign the admin out or revoke the test robot mid-run

            @settings(max_examples=EXAMPLES_PER_OPERATION, deadline=None, database=None,
                      suppress_health_check=list(HealthCheck))  # fmt: skip
            @given(case=operation.as_strategy())
            def check(case) -> None:
                response = case.call(base_url=server.http, headers=headers, timeout=10)
                if response.status_code >= 500:
                    failures.append(
                        f"{case.method} {case.formatted_path} -> {response.status_code}: "
                        f"{response.text[:200]}"
                    )

            check()
    assert not failures, "\n".join(failures[:20])
