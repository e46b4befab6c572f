"""Docker cannot run here: check docker-compose.yml's structure, build contexts and commands."""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
COMPOSE = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
SCRIPTS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
EXPECTED = {"postgres", "redis", "migrate", "backend", "worker", "robot-sim"}


def _module_exists(dotted: str) -> bool:
    return importlib.util.find_spec(dotted) is not None


def _argparse_subcommands(module: str) -> set[str]:
    source = (ROOT / (module.replace(".", "/") + ".py")).read_text()
    return set(re.findall(r"add_parser\(\s*\"([a-z-]+)\"", source))


def test_compose_has_every_service_with_healthchecks_and_ordering():
    services = COMPOSE["services"]
    assert set(services) >= EXPECTED
    for name in ("postgres", "redis", "backend"):
        assert "healthcheck" in services[name], name
    assert services["migrate"]["depends_on"]["postgres"]["condition"] == "service_healthy"
    for name in ("backend", "worker"):
        condition = services[name]["depends_on"]["migrate"]["condition"]
        assert condition == "service_completed_successfully"
    assert "pgdata" in COMPOSE["volumes"]
    assert any(v.startswith("pgdata:") for v in services["postgres"]["volumes"])


def test_every_build_context_and_dockerfile_exists():
    for name, service in COMPOSE["services"].items():
        build = service.get("build")
        if build is None:
            assert "image" in service, f"{name} has neither build nor image"
            continue
        context = ROOT / build["context"]
        assert context.is_dir(), name
        dockerfile = context / build["dockerfile"]
        assert dockerfile.is_file(), f"{name}: {dockerfile} missing"
        for line in dockerfile.read_text().splitlines():
            if line.startswith("COPY ") and "--from=" not in line:
                for source in line.split()[1:-1]:
                    assert (context / source).exists(), f"{dockerfile.name}: {source} missing"


def test_every_service_command_exists_in_the_repository():
    for name, service in COMPOSE["services"].items():
        if "build" not in service:
            continue
        command = service["command"]
        script, subcommand = command[0], command[1]
        assert script in SCRIPTS, f"{name}: console script {script} not declared"
        module = SCRIPTS[script].split(":")[0]
        assert _module_exists(module), f"{name}: {module} does not exist"
        assert subcommand in _argparse_subcommands(module), (
            f"{name}: {script} has no subcommand {subcommand}"
        )
