"""Sign-in: lockout with exponential backoff per user and per client (429 + Retry-After), the
same cost for unknown and existing users, and bounded password hashing (503 when saturated)."""

from __future__ import annotations

import asyncio
import os
import statistics
import threading
import time

import pytest

from backend.accounts import queries, service
from backend.accounts.gate import HashingBusy, HashingGate
from backend.accounts.throttle import LoginThrottle, Policy
from backend.db import transaction
from backend.models import Role, User
from backend.security import hash_password
from tests.backend.conftest import PASSWORD

LOGIN = "/api/auth/login"


@pytest.fixture
def settings(settings):
    settings.login_user_free_failures = 5
    settings.login_client_free_failures = 20
    settings.login_lockout_base_s = 30
    return settings


def add_user(session_factory, username: str = "nora", active: bool = True) -> None:
    with transaction(session_factory) as session:
        session.add(
            User(
                username=username,
                password_hash=hash_password(PASSWORD),
                role=Role.NURSE,
                ward="ward-a",
                active=active,
            )
        )


def test_sixty_wrong_passwords_lock_the_account_and_the_right_one_then_gets_429(
    client, session_factory
):
    add_user(session_factory)
    statuses = [
        client.post(LOGIN, json={"username": "nora", "password": f"guess-{i}"}).status_code
        for i in range(60)
    ]
    assert statuses[:5] == [401] * 5  # the free failures are verified and refused
    assert set(statuses[5:]) == {429}  # then locked: no more guesses get verified
    right = client.post(LOGIN, json={"username": "nora", "password": PASSWORD})
    assert right.status_code == 429
    assert int(right.headers["Retry-After"]) >= 30
    assert "try again" in right.json()["detail"]


def test_the_lockout_is_per_user_name_and_a_success_before_it_clears_the_count(
    client, session_factory
):
    add_user(session_factory, "nora")
    add_user(session_factory, "nils")
    for _ in range(4):
        assert client.post(LOGIN, json={"username": "nora", "password": "x"}).status_code == 401
    assert client.post(LOGIN, json={"username": "nora", "password": PASSWORD}).status_code == 200
    client.cookies.clear()  # a cookie-carrying POST without Origin would be refused (CSRF)
    for _ in range(4):  # counted from zero again: still below the 5 free failures
        assert client.post(LOGIN, json={"username": "nora", "password": "x"}).status_code == 401
    assert client.post(LOGIN, json={"username": "nora", "password": PASSWORD}).status_code == 200
    client.cookies.clear()
    for _ in range(5):
        client.post(LOGIN, json={"username": "nora", "password": "x"})
    assert client.post(LOGIN, json={"username": "nora", "password": PASSWORD}).status_code == 429
    # Another user from the same client is not locked by nora's lockout.
    assert client.post(LOGIN, json={"username": "nils", "password": PASSWORD}).status_code == 200


def test_one_client_spraying_many_user_names_is_locked_out(client, session_factory):
    add_user(session_factory, "nora")
    for i in range(20):  # one guess per user name: no user lockout, the client's count grows
        response = client.post(LOGIN, json={"username": f"user-{i}", "password": "x"})
        assert response.status_code == 401
    locked = client.post(LOGIN, json={"username": "nora", "password": PASSWORD})
    assert locked.status_code == 429 and "Retry-After" in locked.headers


def test_backoff_doubles_with_each_failure_up_to_the_cap_and_is_forgotten_later():
    now = [1000.0]
    policy = Policy(free=3, base_s=1, max_s=8)
    throttle = LoginThrottle(policy, Policy(1000, 1, 8), memory_s=3600, clock=lambda: now[0])
    assert [throttle.failed("u", "c") for _ in range(2)] == [0, 0]
    assert throttle.retry_after("u", "c") == 0
    waits = [throttle.failed("u", "c") for _ in range(5)]
    assert waits == [1, 2, 4, 8, 8]
    assert throttle.retry_after("U", "other-client") == 8  # user names compare case-blind
    now[0] += 8
    assert throttle.retry_after("u", "c") == 0
    now[0] += 3601  # an hour without failures: forgotten, the next failure is a free one again
    assert throttle.failed("u", "c") == 0


def test_unknown_and_existing_users_cost_the_same_verification(session_factory):
    add_user(session_factory, "nora")
    add_user(session_factory, "gone", active=False)

    def median_ms(username: str, password: str) -> float:
        times = []
        for _ in range(5):
            with session_factory() as session:
                user = queries.user_by_username(session, username)
            start = time.perf_counter()
            assert service.password_matches(user, password) is False
            times.append((time.perf_counter() - start) * 1000)
        return statistics.median(times)

    median_ms("nobody", "warm-up")  # the dummy hash is made once, on first use
    unknown = median_ms("nobody", "wrong")
    existing = median_ms("nora", "wrong")
    inactive = median_ms("gone", PASSWORD)  # right password, deactivated: refused, same cost
    # Before the fix: 3.4 ms against 265 ms (a 78x ratio).
    assert 0.5 < unknown / existing < 2, (unknown, existing)
    assert 0.5 < inactive / existing < 2, (inactive, existing)


def test_a_four_lane_hash_is_upgraded_to_one_lane_at_sign_in(client, session_factory):
    from argon2 import PasswordHasher
    from sqlalchemy import select

    with transaction(session_factory) as session:
        session.add(
            User(
                username="old",
                password_hash=PasswordHasher(parallelism=4).hash(PASSWORD),
                role=Role.NURSE,
                ward="ward-a",
            )
        )
    assert client.post(LOGIN, json={"username": "old", "password": PASSWORD}).status_code == 200
    with session_factory() as session:
        stored = session.scalars(select(User).where(User.username == "old")).one().password_hash
    assert ",p=1$" in stored
    client.cookies.clear()
    assert client.post(LOGIN, json={"username": "old", "password": PASSWORD}).status_code == 200


def test_sign_in_answers_unknown_and_existing_users_in_the_same_time(client, session_factory):
    for i in range(4):
        add_user(session_factory, f"user-{i}")

    def median_ms(prefix: str) -> float:
        times = []
        for i in range(4):  # one attempt per user name: below every lockout
            start = time.perf_counter()
            response = client.post(LOGIN, json={"username": f"{prefix}-{i}", "password": "x"})
            times.append((time.perf_counter() - start) * 1000)
            assert response.status_code == 401
            assert response.json()["detail"] == "wrong username or password"
        return statistics.median(times)

    client.post(LOGIN, json={"username": "warm-up", "password": "x"})
    unknown, existing = median_ms("nobody"), median_ms("user")
    assert 0.5 < unknown / existing < 2, (unknown, existing)


def test_the_gate_runs_at_most_its_concurrency_and_refuses_beyond_its_queue():
    running, peak, lock = [0], [0], threading.Lock()

    def verify() -> str:
        with lock:
            running[0] += 1
            peak[0] = max(peak[0], running[0])
        time.sleep(0.05)
        with lock:
            running[0] -= 1
        return "ok"

    async def flood(gate: HashingGate, n: int) -> list:
        return await asyncio.gather(*(gate.run(verify) for _ in range(n)), return_exceptions=True)

    results = asyncio.run(flood(HashingGate(1, wait_s=5, queue_max=10), 6))
    assert results == ["ok"] * 6 and peak[0] == 1
    results = asyncio.run(flood(HashingGate(1, wait_s=5, queue_max=2), 6))
    # one running, two waiting; the other three refused at once
    assert results.count("ok") == 3
    assert sum(isinstance(r, HashingBusy) for r in results) == 3
    results = asyncio.run(flood(HashingGate(1, wait_s=0.01, queue_max=10), 3))
    assert results[0] == "ok" and all(isinstance(r, HashingBusy) for r in results[1:])


def test_hashing_runs_at_a_lower_priority_than_ingest():
    def priority() -> int:
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())

    async def measure() -> int:
        gate = HashingGate(1, wait_s=1, queue_max=1, nice=10)
        try:
            return await gate.run(priority)
        finally:
            gate.close()

    assert asyncio.run(measure()) == min(19, priority() + 10)


def test_a_saturated_gate_answers_503_with_retry_after(client, session_factory):
    add_user(session_factory)
    state = client.app.state.services
    state.login_gate = HashingGate(1, wait_s=0.05, queue_max=5)

    async def hold_the_slot() -> None:
        await state.login_gate._slots.acquire()

    async def release_the_slot() -> None:
        state.login_gate._slots.release()

    client.portal.call(hold_the_slot)
    busy = client.post(LOGIN, json={"username": "nora", "password": PASSWORD})
    assert busy.status_code == 503
    assert busy.headers["Retry-After"] == "1"
    client.portal.call(release_the_slot)
    assert client.post(LOGIN, json={"username": "nora", "password": PASSWORD}).status_code == 200
