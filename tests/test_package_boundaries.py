"""The layering: `vigil` imports no web, database or other Vigil package; the robot agent
imports `vigil` and nothing of the server side; the backend never imports the robot agent."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

FORBIDDEN = {
    "vigil": {"fastapi", "starlette", "sqlalchemy", "alembic", "backend", "worker",
              "robot_agent", "uvicorn", "redis", "psycopg"},
    "robot_agent": {"fastapi", "starlette", "sqlalchemy", "alembic", "backend", "worker",
                    "uvicorn", "redis", "psycopg", "torch", "sklearn"},
    "backend": {"robot_agent"},
}  # fmt: skip


def imported_top_levels(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_respect_the_layering(package):
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = imported_top_levels(path) & FORBIDDEN[package]
        if bad:
            offenders.append(f"{path.relative_to(ROOT)}: {sorted(bad)}")
    assert not offenders, "\n".join(offenders)
