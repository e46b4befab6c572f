"""Demo accounts and robots for `make run` (idempotent)."""

from __future__ import annotations

import json
import secrets
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models._types import utcnow
from backend.models.robots import Robot
from backend.models.users import Role, User
from backend.security import hash_password, hash_robot_token, new_robot_token, verify_password

DEMO_WARD = "ward-3a"
DEMO_USERS = (
    ("annotator", Role.ANNOTATOR, None),
    ("nurse", Role.NURSE, DEMO_WARD),
    ("engineer", Role.ENGINEER, None),
    ("admin", Role.ADMIN, None),
)
#: The fixed passwords earlier versions set; a demo user still on one gets a generated one.
LEGACY_PASSWORD_SUFFIX = "-demo-pass"


def _write_private(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.touch(mode=0o600)
    path.chmod(0o600)
    path.write_text(json.dumps(data, indent=2))


def ensure_demo_users(session: Session, passwords_file: Path) -> list[tuple[str, str | None, Role]]:
    """Create one user per role with a password generated for this machine, kept in
    `passwords_file` (mode 600) so a second run prints the same ones. Returns (username,
    password or None when the user exists with a password this file does not know, role)."""
    passwords: dict[str, str] = {}
    if passwords_file.exists():
        passwords = json.loads(passwords_file.read_text())
    credentials: list[tuple[str, str | None, Role]] = []
    for username, role, ward in DEMO_USERS:
        user = session.scalars(select(User).where(User.username == username)).first()
        if user is None:
            user = User(username=username, display_name=username.title(), role=role, ward=ward)
            session.add(user)
        elif username in passwords and verify_password(user.password_hash, passwords[username]):
            credentials.append((username, passwords[username], role))
            continue
        elif not verify_password(user.password_hash, username + LEGACY_PASSWORD_SUFFIX):
            passwords.pop(username, None)
            credentials.append((username, None, role))  # someone set it: leave it alone
            continue
        passwords[username] = secrets.token_urlsafe(12)
        user.password_hash = hash_password(passwords[username])
        credentials.append((username, passwords[username], role))
    _write_private(passwords_file, passwords)
    return credentials


def ensure_demo_robots(session: Session, count: int, tokens_file: Path) -> dict[str, str]:
    """Create robots robot-1..N in the demo ward; their tokens are kept in `tokens_file`
    (mode 600) so a second run reuses them."""
    tokens: dict[str, str] = {}
    if tokens_file.exists():
        tokens = json.loads(tokens_file.read_text())
    for i in range(1, count + 1):
        robot_id = f"robot-{i}"
        robot = session.get(Robot, robot_id)
        if robot is None:
            robot = Robot(id=robot_id, name=f"Transport robot {i}", ward=DEMO_WARD)
            session.add(robot)
        if robot_id not in tokens or robot.token_hash != hash_robot_token(tokens[robot_id]):
            tokens[robot_id] = new_robot_token()
            robot.token_hash = hash_robot_token(tokens[robot_id])
            robot.token_created_at = utcnow()
    _write_private(tokens_file, tokens)
    return tokens


def seed_urfd(session: Session, directory: Path | str | None = None):
    """URFD (real data) into the labelling workspace, through the one URFD importer: one video
    per recording, 56 training and 14 gold; the worker's bootstrap finds them there."""
    from backend.labelling.importers.urfd import import_urfd

    return import_urfd(session, directory)
