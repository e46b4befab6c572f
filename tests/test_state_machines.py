"""Every state machine is declared through `vigil.states`, and only its `move`/`act`/`start`
change a state attribute: these tests read the source (ast) and fail on a direct assignment
(`x.status = ...`, `x.state = ...`, `setattr(x, "status", ...)`, `.values(status=...)` in an
SQL update), on a transition table written by hand, and on a state enum without a machine."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("vigil", "backend", "worker", "robot_agent", "scripts", "bench", "migrations")
HELPER = ROOT / "vigil" / "states.py"
#: Attributes that hold a machine's state (the tracker's is `state_`, a learned attribute).
STATE_ATTRIBUTES = {"status", "state", "state_"}
#: State enums that are no machine: computed on demand, never stored or changed.
NOT_MACHINES = {"ConnectionState"}  # backend/realtime/robot_registry.py: connected or not, derived


def sources() -> list[tuple[Path, ast.Module]]:
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if path != HELPER:
                found.append((path, ast.parse(path.read_text(), str(path))))
    return found


def _targets(node: ast.AST) -> list[ast.expr]:
    if isinstance(node, ast.Assign):
        targets = list(node.targets)
    elif isinstance(node, ast.AugAssign | ast.AnnAssign):
        targets = [node.target]
    else:
        return []
    flat = []
    while targets:
        target = targets.pop()
        if isinstance(target, ast.Tuple | ast.List):
            targets.extend(target.elts)
        else:
            flat.append(target)
    return flat


def direct_state_writes(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, what) for every write of a state attribute that bypasses the helper."""
    writes = []
    for node in ast.walk(tree):
        for target in _targets(node):
            if isinstance(target, ast.Attribute) and target.attr in STATE_ATTRIBUTES:
                writes.append((node.lineno, f".{target.attr} ="))
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if (
            isinstance(func, ast.Name)
            and func.id == "setattr"
            and len(node.args) >= 2
            and isinstance(node.args[1], ast.Constant)
            and node.args[1].value in STATE_ATTRIBUTES
        ):
            writes.append((node.lineno, f"setattr(..., {node.args[1].value!r})"))
        # Created straight into a state: Segment(status=SegmentStatus.ACCEPTED). A new object
        # starts through its machine (`start(obj)`, or a declared entry `start(obj, "import")`).
        for keyword in node.keywords:
            value = keyword.value
            if (
                keyword.arg in STATE_ATTRIBUTES
                and isinstance(value, ast.Attribute)
                and isinstance(value.value, ast.Name)
                and value.value.id.endswith(("State", "Status"))
                and not (isinstance(func, ast.Attribute) and func.attr in ("where", "filter_by"))
            ):
                writes.append(
                    (node.lineno, f"created with {keyword.arg}={value.value.id}.{value.attr}")
                )
        if isinstance(func, ast.Attribute) and func.attr == "values":
            for keyword in node.keywords:
                if keyword.arg in STATE_ATTRIBUTES:
                    writes.append((node.lineno, f".values({keyword.arg}=...)"))
            for arg in node.args:
                if isinstance(arg, ast.Dict):
                    for key in arg.keys:
                        if isinstance(key, ast.Constant) and key.value in STATE_ATTRIBUTES:
                            writes.append((node.lineno, f".values({{{key.value!r}: ...}})"))
    return writes


def test_the_scan_finds_every_kind_of_direct_write():
    code = """
job.status = "running"
self.state_ = TrackState.LOST
a.x, alarm.state = 1, "open"
setattr(segment, "status", "draft")
update(Job).values(status="running")
update(Job).values({"state": "open"})
TRACKER.move(self, TrackState.LOST)
update(Job).values(**JOB.column(job.status, JobStatus.RUNNING, job), worker_id="w")
Job(status=JOB.initial)
AnnotationSegment(video_id=1, status=SegmentStatus.ACCEPTED)
SEGMENT.start(segment, "import")
select(Job).where(Job.status == JobStatus.RUNNING).filter_by(status=JobStatus.RUNNING)
"""
    writes = [what for _, what in direct_state_writes(ast.parse(code))]
    assert sorted(writes) == sorted(
        [
            ".status =",
            ".state_ =",
            ".state =",
            "setattr(..., 'status')",
            ".values(status=...)",
            ".values({'state': ...})",
            "created with status=SegmentStatus.ACCEPTED",
        ]
    )


#: Modules that put stored rows back as they were (not a creation): restoring an archived
#: video re-inserts its dataset labels, accepted as they were imported.
RESTORES = {"backend/storage/archive.py"}


def test_no_state_attribute_is_assigned_outside_the_helper():
    offenders = [
        f"{path.relative_to(ROOT)}:{line}: {what} (use the machine's move/act/start)"
        for path, tree in sources()
        for line, what in direct_state_writes(tree)
        if not (what.startswith("created with") and str(path.relative_to(ROOT)) in RESTORES)
    ]
    assert not offenders, "\n".join(offenders)


def test_no_transition_table_is_written_by_hand():
    tables = []
    for path, tree in sources():
        for node in tree.body:
            for target in _targets(node):
                if isinstance(target, ast.Name) and target.id in {"ALLOWED", "TRANSITIONS"}:
                    tables.append(f"{path.relative_to(ROOT)}:{node.lineno}: {target.id}")
    assert not tables, "declare it with vigil.states.StateMachine:\n" + "\n".join(tables)


def test_every_state_enum_is_declared_as_a_machine():
    enums: dict[str, str] = {}
    declared: set[str] = set()
    for path, tree in sources():
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.ClassDef)
                and node.name.endswith(("State", "Status"))
                and any(isinstance(b, ast.Name) and b.id.endswith("Enum") for b in node.bases)
            ):
                enums[node.name] = str(path.relative_to(ROOT))
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id == "StateMachine"
                and node.args
                and isinstance(node.args[0], ast.Name)
            ):
                declared.add(node.args[0].id)
    assert {
        "AlarmState",
        "SegmentStatus",
        "JobStatus",
        "ModelStatus",
        "DeploymentStatus",
        "TrackState",
    } <= declared
    missing = {name: where for name, where in enums.items() if name not in declared}
    assert set(missing) == NOT_MACHINES, f"state enums without a StateMachine: {missing}"
