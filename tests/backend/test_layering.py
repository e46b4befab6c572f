"""House rules of the backend, checked on the source: routers hold no SQL (queries live in each
domain's `queries.py`), and services are reached through `backend.services`, not as loose
attributes of `app.state`."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ROUTERS = sorted((ROOT / "backend" / "api").rglob("*.py")) + [ROOT / "backend" / "main.py"]
SQL_CALLS = {"select", "insert", "update", "delete", "text", "query", "execute", "scalar",
             "scalars"}  # fmt: skip


def calls(path: Path) -> list[tuple[int, str]]:
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Attribute) and getattr(func.value, "id", "") in (
                "router",
                "app",
            ):
                continue  # a route decorator: @router.delete(...)
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            out.append((node.lineno, name))
    return out


def test_routers_hold_no_sql():
    offenders = [
        f"{path.relative_to(ROOT)}:{line}: {name}("
        for path in ROUTERS
        for line, name in calls(path)
        if name in SQL_CALLS
    ]
    assert not offenders, "SQL in a router (move it to a queries.py):\n" + "\n".join(offenders)


def test_app_state_holds_only_the_services():
    offenders = []
    for path in sorted((ROOT / "backend").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Attribute)
                and node.value.attr == "state"
                and isinstance(node.value.value, ast.Attribute | ast.Name)
                and getattr(node.value.value, "attr", getattr(node.value.value, "id", "")) == "app"
                and node.attr != "services"
            ):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: app.state.{node.attr}")
    assert not offenders, "\n".join(offenders)
