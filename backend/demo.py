"""Demo accounts and robots for `make run` (idempotent)."""

from __future__ import annotations

import json
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models._types import utcnow
from backend.models.robots import Robot
from backend.models.users import Role, User
from backend.security import hash_password, hash_robot_token, new_robot_token

DEMO_WARD = "ward-3a"
DEMO_USERS = (
    ("annotator", Role.ANNOTATOR, None),
    ("nurse", Role.NURSE, DEMO_WARD),
    ("engineer", Role.ENGINEER, None),
    ("admin", Role.ADMIN, None),
)
DEMO_PASSWORD_SUFFIX = "-demo-pass"


def ensure_demo_users(session: Session) -> list[tuple[str, str, Role]]:
    """Create one user per role; returns (username, password, role) for printing."""
    credentials = []
    for username, role, ward in DEMO_USERS:
        password = username + DEMO_PASSWORD_SUFFIX
        if session.scalars(select(User).where(User.username == username)).first() is None:
            session.add(
                User(
                    username=username,
                    display_name=username.title(),
                    password_hash=hash_password(password),
                    role=role,
                    ward=ward,
                )
            )
        credentials.append((username, password, role))
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
    tokens_file.parent.mkdir(parents=True, exist_ok=True)
    tokens_file.touch(mode=0o600)
    tokens_file.write_text(json.dumps(tokens, indent=2))
    return tokens
