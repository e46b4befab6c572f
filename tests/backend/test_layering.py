"""House rules of the backend, checked on the source: routers hold no SQL (queries live in each
domain's `queries.py`), services are reached through `backend.services`, not as loose
attributes of `app.state`, no two parts of the backend import each other, and the web layer
(`api/`, `main.py`) is on top: nothing below imports it."""

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


WEB_LAYER = {"api", "main"}
# The process entry points stand above the web layer: they start it.
ENTRY_POINTS = {"cli", "openapi"}


def _part(module: str) -> str:
    """backend.alarms.service -> alarms; backend.unit_of_work -> unit_of_work."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "backend"


def backend_imports() -> dict[str, set[tuple[str, str]]]:
    """part of backend -> {(imported part, where)}, every import, also inside functions."""
    edges: dict[str, set[tuple[str, str]]] = {}
    for path in sorted((ROOT / "backend").rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        me = rel.parts[1] if len(rel.parts) > 1 and rel.parts[1] != "__init__" else "backend"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                modules = [node.module]
                if node.module == "backend":
                    modules = [f"backend.{alias.name}" for alias in node.names]
            else:
                continue
            for module in modules:
                if module.startswith("backend.") and _part(module) != me:
                    edges.setdefault(me, set()).add((_part(module), f"{rel}:{node.lineno}"))
    return edges


def test_no_two_parts_of_the_backend_import_each_other():
    edges = backend_imports()
    targets = {part: {other for other, _ in out} for part, out in edges.items()}
    pairs = sorted(
        {
            tuple(sorted((a, b)))
            for a, out in targets.items()
            for b in out
            if a in targets.get(b, ())
        }
    )
    where = [
        f"{a} <-> {b}: "
        + ", ".join(sorted(w for x, y in ((a, b), (b, a)) for other, w in edges[x] if other == y))
        for a, b in pairs
    ]
    assert not pairs, "two-way imports inside backend/:\n" + "\n".join(where)


def test_nothing_below_the_web_layer_imports_it():
    offenders = sorted(
        where
        for part, out in backend_imports().items()
        if part not in WEB_LAYER | ENTRY_POINTS
        for other, where in out
        if other in WEB_LAYER
    )
    assert not offenders, "imports of the web layer (api/, main.py) from below:\n" + "\n".join(
        offenders
    )
