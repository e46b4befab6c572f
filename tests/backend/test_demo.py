"""`seed-demo`: demo passwords are generated for this machine (not fixed), printed, kept in a
mode-600 file so a rerun prints the same ones; a demo user still on an old fixed password gets
a generated one, a password someone set is left alone."""

from __future__ import annotations

import re

from sqlalchemy import select

from backend import cli
from backend.db import transaction
from backend.demo import DEMO_USERS, ensure_demo_users
from backend.models import User
from backend.security import hash_password, verify_password


def password_of(session_factory, username: str) -> str:
    with session_factory() as session:
        return session.scalars(select(User).where(User.username == username)).one().password_hash


def test_seed_demo_prints_generated_passwords_that_sign_in(
    database_url, session_factory, tmp_path, monkeypatch, capsys
):
    monkeypatch.setenv("VIGIL_DATABASE_URL", database_url)
    monkeypatch.setenv("VIGIL_SECRET_KEY", "demo-test")
    passwords_file = tmp_path / "demo_passwords.json"
    args = [
        "seed-demo",
        "--no-urfd",
        "--robots",
        "1",
        "--tokens-file",
        str(tmp_path / "t.json"),
        "--passwords-file",
        str(passwords_file),
    ]
    assert cli.main(args) == 0
    printed = dict(re.findall(r"user (\w+)\s+password (\S+)", capsys.readouterr().out))
    assert set(printed) == {username for username, _, _ in DEMO_USERS}
    for username, password in printed.items():
        assert password != username + "-demo-pass"  # the fixed password before the fix
        assert len(password) >= 12
        assert verify_password(password_of(session_factory, username), password)
    assert passwords_file.stat().st_mode & 0o777 == 0o600

    assert cli.main(args) == 0  # idempotent: the same passwords again
    again = dict(re.findall(r"user (\w+)\s+password (\S+)", capsys.readouterr().out))
    assert again == printed


def test_two_machines_get_different_passwords(session_factory, tmp_path):
    with transaction(session_factory) as session:
        first = ensure_demo_users(session, tmp_path / "a.json")
    with transaction(session_factory) as session:
        session.execute(User.__table__.delete())
    with transaction(session_factory) as session:
        second = ensure_demo_users(session, tmp_path / "b.json")
    assert {p for _, p, _ in first}.isdisjoint({p for _, p, _ in second})


def test_legacy_fixed_passwords_are_replaced_and_set_ones_kept(session_factory, tmp_path):
    with transaction(session_factory) as session:
        for username, role, ward in DEMO_USERS:
            password = "chosen-by-admin" if username == "admin" else username + "-demo-pass"
            session.add(
                User(username=username, password_hash=hash_password(password), role=role, ward=ward)
            )
    with transaction(session_factory) as session:
        credentials = {u: p for u, p, _ in ensure_demo_users(session, tmp_path / "p.json")}
    assert credentials["admin"] is None
    assert verify_password(password_of(session_factory, "admin"), "chosen-by-admin")
    assert not verify_password(password_of(session_factory, "nurse"), "nurse-demo-pass")
    assert verify_password(password_of(session_factory, "nurse"), credentials["nurse"])
