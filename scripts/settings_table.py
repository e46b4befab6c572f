"""Print README's configuration table from the settings classes themselves, so the table
cannot drift from the code: `python -m scripts.settings_table` (tests/test_readme.py checks it).
With --write, replace the table between README's settings markers."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
START, END = "<!-- settings:start -->", "<!-- settings:end -->"

#: (process, module, class name)
SETTINGS_CLASSES = (
    ("backend", "backend.settings", "Settings"),
    ("worker", "worker.settings", "WorkerSettings"),
    ("robot agent", "robot_agent.config", "AgentSettings"),
)


def _default(value) -> str:
    text = str(value)
    text = text.replace(str(ROOT), "<repo>")
    return f"`{text}`" if text else '`""`'


def table() -> str:
    rows = ["| process | environment variable | default | meaning |", "| --- | --- | --- | --- |"]
    for process, module_name, class_name in SETTINGS_CLASSES:
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except (ImportError, AttributeError):
            continue
        prefix = cls.model_config.get("env_prefix", "")
        for name, field in cls.model_fields.items():
            env = (prefix + name).upper()
            meaning = (field.description or "").replace("|", "\\|")
            default = _default(field.default) if field.default_factory is None else "(computed)"
            rows.append(f"| {process} | `{env}` | {default} | {meaning} |")
    return "\n".join(rows)


def readme_table() -> str | None:
    text = README.read_text()
    if START not in text or END not in text:
        return None
    return text.split(START, 1)[1].split(END, 1)[0].strip()


def write() -> None:
    text = README.read_text()
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    README.write_text(f"{head}{START}\n{table()}\n{END}{tail}")


if __name__ == "__main__":
    if "--write" in sys.argv:
        write()
    else:
        print(table())
