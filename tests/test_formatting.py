"""Formatting belongs to the formatter: no source file opts out of it (issue 35)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vigil", "backend", "worker", "robot_agent", "tests", "bench", "migrations", "scripts")
OPT_OUTS = ("fmt: skip", "fmt: off", "yapf: disable")


def test_no_source_file_opts_out_of_the_formatter():
    this_file = Path(__file__).resolve()
    found = [
        f"{path.relative_to(ROOT)}:{number}"
        for package in PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
        if path.resolve() != this_file
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if any(f"# {marker}" in line for marker in OPT_OUTS)
    ]
    assert not found, f"formatter opt-outs left in: {found}"
