"""House rules of the backend, checked on the source: SQL is built only below the web layer,
in the domain folders (a domain's reads in its `queries.py`, its services' and storage
mechanics' SQL beside them) and a few named database modules; services are reached through
`backend.services`, not as loose attributes of `app.state`; no two parts of the backend import
each other; and the web layer (`api/`, `main.py`, `deps.py`) is on top: nothing below imports
it."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ROUTERS = sorted((ROOT / "backend" / "api").rglob("*.py")) + [ROOT / "backend" / "main.py"]
SQL_CALLS = {
    "select",
    "insert",
    "update",
    "delete",
    "text",
    "query",
    "execute",
    "scalar",
    "scalars",
}


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


#: The modules of backend/ outside a domain folder that build SQL, each for a reason of its own.
SQL_MODULES = {
    "db.py": "engine set-up: the SQLite pragmas",
    "health.py": "the readiness probe's SELECT 1",
    "leadership.py": "PostgreSQL advisory locks (the duties and retention locks)",
    "wards.py": "the ward clauses every domain's queries share",
    "demo.py": "the demo accounts and robots of `make run`",
}
#: Folders of backend/ that are no domain: the web layer (no SQL) and the table definitions
#: (only `text(...)` in index expressions).
NOT_DOMAINS = {"api", "models"}


def sql_outside_its_places(backend: Path) -> list[str]:
    """`path:line: call(` for each SQL call in a module of `backend` where the rule allows none:
    the web layer (`api/`, `main.py`, `deps.py`), the glue (`services.py`, `unit_of_work.py`)
    and every other top-level module not in SQL_MODULES; in `models/` only `text(` (index
    expressions). Anything goes in a domain folder."""
    offenders = []
    for path in sorted(backend.rglob("*.py")):
        rel = path.relative_to(backend)
        folder = rel.parts[0] if len(rel.parts) > 1 else None
        if folder not in NOT_DOMAINS and (folder is not None or rel.name in SQL_MODULES):
            continue
        allowed = {"text"} if folder == "models" else set()
        offenders += [
            f"backend/{rel.as_posix()}:{line}: {name}("
            for line, name in calls(path)
            if name in SQL_CALLS - allowed
        ]
    return offenders


def test_sql_is_built_only_in_the_domain_folders_and_the_named_database_modules():
    offenders = sql_outside_its_places(ROOT / "backend")
    assert not offenders, (
        "SQL outside a domain folder (put it in the domain's queries.py or service):\n"
        + "\n".join(offenders)
    )
    for name in SQL_MODULES:
        assert any(n in SQL_CALLS for _, n in calls(ROOT / "backend" / name)), (
            f"backend/{name} builds no SQL any more: take it off SQL_MODULES"
        )


def test_the_sql_scan_finds_sql_in_the_web_layer_the_glue_and_the_tables(tmp_path):
    for rel in (
        "api/x.py",
        "main.py",
        "deps.py",
        "services.py",
        "unit_of_work.py",
        "models/t.py",
        "alarms/service.py",
        "storage/partitions.py",
        "health.py",
    ):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("session.execute(select(A))\nIndex('i', text('x'))\n")
    found = sql_outside_its_places(tmp_path)
    assert sorted({f.split(":")[0] for f in found}) == [
        "backend/api/x.py",
        "backend/deps.py",
        "backend/main.py",
        "backend/models/t.py",
        "backend/services.py",
        "backend/unit_of_work.py",
    ]
    assert sorted(f for f in found if "models" in f) == [
        "backend/models/t.py:1: execute(",
        "backend/models/t.py:1: select(",
    ]


#: The routers, the app and its FastAPI dependencies (`deps.py`: sessions, the current user).
WEB_LAYER = {"api", "main", "deps"}
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


def web_layer_imports(edges: dict[str, set[tuple[str, str]]]) -> list[str]:
    return sorted(
        where
        for part, out in edges.items()
        if part not in WEB_LAYER | ENTRY_POINTS
        for other, where in out
        if other in WEB_LAYER
    )


def test_nothing_below_the_web_layer_imports_it():
    offenders = web_layer_imports(backend_imports())
    assert not offenders, "imports of the web layer (api/, main.py, deps.py) from below:\n" + (
        "\n".join(offenders)
    )


def test_a_domain_folder_importing_deps_is_an_offence():
    """`backend.deps` is the web layer's: a domain takes shared column limits (MAX_DB_INT) from
    `backend.models`, not from it."""
    edges = {
        "labelling": {("deps", "backend/labelling/schemas:10"), ("models", "x:1")},
        "api": {("deps", "backend/api/videos:8")},
    }
    assert web_layer_imports(edges) == ["backend/labelling/schemas:10"]
