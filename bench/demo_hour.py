"""An hour of `make run`, measured: does the board show the simulated ward's falls, newest first?

Starts `make run`'s system (`python -m scripts.run_all`: migrations, demo seeding, first-run
training, registry bootstrap, backend, worker and the simulated fleet of 3 robots) on a
throwaway data directory (VIGIL_VAR_DIR) and a free port, waits until it says it is running,
lets it run `--minutes` (60), then reads the ward board as the demo nurse would:

- through the API: open (unacknowledged or missed) Emergency alarms of the ward, against the
  falls the simulated fleet generated (each GENERATED transport's events are in the fleet's log)
  and against the configured rate (falls per robot per hour x robots x hours);
- in Chromium: the board's first card, against the newest open Emergency;
- the models the robots run: each one's registry status and promotion gate, and the fleet's
  log lines that warn about floor measures (issue 17: the demo runs models its robots can feed).

Counts and order, not speed: run it under `nice`. The skeletons are GENERATED
(vigil.synthetic); the models are trained on URFD (real data) plus GENERATED walking
transports (`train-default --with-generated`) and gated on URFD's gold set.

    python -m bench.demo_hour [--minutes 60] [--out bench/results/demo_hour.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "results" / "demo_hour.json"
ROBOTS = 3  # scripts.run_all.ROBOTS
WARD = "ward-3a"  # backend.demo.DEMO_WARD
STARTED = re.compile(
    r"robot (?P<robot>\S+): transport (?P<transport>\S+) started .*?"
    r"(?:; GENERATED events: (?P<events>.+))?$"
)
OPEN_STATES = ("open", "missed")  # what still needs a person: not acknowledged, not resolved


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_line(log: Path, text: str, process: subprocess.Popen, timeout_s: float) -> float:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise SystemExit(f"make run exited with code {process.returncode}; see {log}")
        if text in log.read_text(errors="replace"):
            return time.monotonic()
        time.sleep(2)
    raise SystemExit(f"make run did not print {text!r} within {timeout_s:.0f} s; see {log}")


def generated_falls(log_text: str) -> dict:
    """Transports and falls per robot, from the fleet's log (its GENERATED ground truth)."""
    from vigil.synthetic import EMERGENCY_EVENTS

    falls_events = {e for events in EMERGENCY_EVENTS.values() for e in events}
    transports: Counter[str] = Counter()
    falls: Counter[str] = Counter()
    events: Counter[str] = Counter()
    by_transport: dict[str, list[str]] = {}
    for line in log_text.splitlines():
        match = STARTED.search(line)
        if not match:
            continue
        transports[match["robot"]] += 1
        by_transport[match["transport"]] = [e for e in (match["events"] or "").split(", ") if e]
        for event in by_transport[match["transport"]]:
            events[event] += 1
            falls[match["robot"]] += event in falls_events
    return {
        "transports": dict(transports),
        "falls": dict(falls),
        "falls_total": sum(falls.values()),
        "events": dict(events),
        "fall_transports": sorted(
            t for t, names in by_transport.items() if set(names) & falls_events
        ),
        "events_by_transport": by_transport,
    }


def alarms_against_falls(alarms: list[dict], generated: dict) -> dict:
    """The board's Emergency alarms against the fleet's ground truth, per transport: alarms on
    a transport with a generated fall, alarms on one without (false alarms, by what the
    transport held), and generated falls with no Emergency alarm."""
    emergencies = [a for a in alarms if a["kind"] == "emergency"]
    falls = set(generated["fall_transports"])
    alarmed = {a["transport_id"] for a in emergencies}
    false = [a for a in emergencies if a["transport_id"] not in falls]
    return {
        "emergency_alarms": len(emergencies),
        "on_a_generated_fall": sum(a["transport_id"] in falls for a in emergencies),
        "false_alarms": len(false),
        "false_alarms_by_event": dict(
            Counter(
                ", ".join(generated["events_by_transport"].get(a["transport_id"]) or ["unknown"])
                for a in false
            )
        ),
        "falls_without_alarm": len(falls - alarmed),
        "falls_without_alarm_events": dict(
            Counter(", ".join(generated["events_by_transport"][t]) for t in falls - alarmed)
        ),
    }


def sign_in(client: httpx.Client, username: str, password: str) -> dict:
    response = client.post("/api/auth/login", json={"username": username, "password": password})
    response.raise_for_status()
    return {"Authorization": f"Bearer {response.json()['access_token']}"}


def board_alarms(client: httpx.Client, headers: dict, since: str) -> list[dict]:
    """The ward's alarms as the nurse's handover lists them (GET /api/handover: every
    unresolved alarm and every one raised since `since`, no page limit; /api/alarms returns
    at most 200)."""
    response = client.get("/api/handover", params={"since": since}, headers=headers)
    response.raise_for_status()
    return [row["alarm"] for row in response.json()["alarms"]]


def board_snapshot(client: httpx.Client, headers: dict, since: str) -> dict:
    return board_summary(board_alarms(client, headers, since))


def board_summary(alarms: list[dict]) -> dict:
    unresolved = [a for a in alarms if a["state"] != "resolved"]
    open_emergencies = [
        a for a in unresolved if a["kind"] == "emergency" and a["state"] in OPEN_STATES
    ]
    newest = max(open_emergencies, key=lambda a: (a["raised_at"], a["id"]), default=None)
    return {
        "unresolved": len(unresolved),
        "unresolved_by_kind_state": dict(Counter(f"{a['kind']}:{a['state']}" for a in unresolved)),
        "open_emergencies": len(open_emergencies),
        "open_emergencies_by_model": dict(Counter(a["model_version"] for a in open_emergencies)),
        "newest_open_emergency": None
        if newest is None
        else {k: newest[k] for k in ("id", "robot_id", "raised_at", "state", "model_version")},
        "open_alarms_of_other_wards": sum(a["ward"] != WARD for a in unresolved),
    }


def _time(text: str) -> datetime:
    return datetime.fromisoformat(text)


def recount(results: Path) -> None:
    """Recount a run's board from its database (for runs whose read went through /api/alarms,
    which returns at most 200 alarms): the ward's alarms raised before the read, in the state
    they had when the system was stopped right after it (no nurse acts in the demo, so an alarm
    unresolved then was unresolved at the read)."""
    from datetime import timedelta

    from sqlalchemy import select

    from backend.alarms.schemas import AlarmOut
    from backend.db import make_engine, make_session_factory
    from backend.models import Alarm

    data = json.loads(results.read_text())
    read_at = datetime.fromisoformat(data["started_at"]) + timedelta(
        seconds=data["setup_s"] + data["measured_minutes"] * 60
    )
    engine = make_engine(f"sqlite:///{Path(data['log']).parent / 'vigil.db'}")
    try:
        with make_session_factory(engine)() as session:
            alarms = [
                AlarmOut.model_validate(a).model_dump(mode="json")
                for a in session.scalars(
                    select(Alarm).where(Alarm.ward == WARD, Alarm.raised_at <= read_at)
                ).unique()
            ]
    finally:
        engine.dispose()
    running_at = read_at - timedelta(minutes=data["measured_minutes"])
    for sample in data["samples"]:
        at = running_at + timedelta(minutes=sample["minutes"])
        then = [
            a
            for a in alarms
            if _time(a["raised_at"]) <= at
            and (a["resolved_at"] is None or _time(a["resolved_at"]) > at)
        ]
        sample.setdefault("through_api", {k: sample[k] for k in ("open_emergencies", "unresolved")})
        sample["unresolved"] = len(then)
        sample["open_emergencies"] = sum(a["kind"] == "emergency" for a in then)
    data.setdefault("board_read_through_api", data["board"])  # a second recount keeps it
    data["board"] = board_summary(alarms)
    data["generated"] = generated_falls(Path(data["log"]).read_text(errors="replace"))
    data["alarms_against_falls"] = alarms_against_falls(
        [a for a in alarms if a["state"] != "resolved"], data["generated"]
    )
    data["board_note"] = (
        "board recounted from the run's database (python -m bench.demo_hour --recount): the "
        "API read of this run went through /api/alarms, which returns at most 200 alarms; "
        f"alarms raised before the read ({read_at.isoformat()}), as stored when the system "
        "stopped right after it"
    )
    newest = data["board"]["newest_open_emergency"]
    data["newest_is_first_card"] = (
        newest is not None and data["board_in_browser"]["first_card_alarm_id"] == newest["id"]
    )
    data["open_emergencies_vs_generated_falls"] = [
        data["board"]["open_emergencies"],
        data["generated"]["falls_total"],
    ]
    results.write_text(json.dumps(data, indent=2) + "\n")
    print(json.dumps(data["board"], indent=2))


def first_card(base_url: str, password: str) -> dict:
    """The board as the nurse sees it in Chromium: its first card and how many cards."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout
    from playwright.sync_api import sync_playwright

    from tests.browser.live_server import CHROMIUM, CHROMIUM_ARGS, TABLET, sign_in

    errors: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport=TABLET)
            page.on("console", lambda m: m.type == "error" and errors.append(m.text))
            sign_in(page, base_url, "nurse", password)
            page.wait_for_url("**/nurse")
            page.locator("main.board[data-link='live']").wait_for(timeout=30_000)
            try:
                page.locator("main.board [data-alarm-id]").first.wait_for(timeout=30_000)
            except PlaywrightTimeout:  # an empty board (a short run, every alarm cleared)
                return {
                    "first_card_alarm_id": None,
                    "first_card_text": None,
                    "cards": 0,
                    "console_errors": errors,
                }
            time.sleep(2)  # the snapshot is in; let the board settle
            first = page.locator("main.board [data-alarm-id]").first
            return {
                "first_card_alarm_id": int(first.get_attribute("data-alarm-id")),
                "first_card_text": " ".join(first.inner_text().split())[:200],
                "cards": page.locator("main.board [data-alarm-id]").count(),
                "console_errors": errors,
            }
        finally:
            browser.close()


def models_run(client: httpx.Client, headers: dict) -> list[dict]:
    """Each robot's model: version, registry status, whether its promotion gate passes."""
    fleet = client.get("/api/fleet", headers=headers).json()
    models = {m["version"]: m for m in client.get("/api/models", headers=headers).json()}
    rows = []
    for robot in fleet:
        row = {
            k: robot.get(k)
            for k in (
                "id",
                "connected",
                "target_version",
                "running_version",
                "in_sync",
                "inputs",
                "fallback_version",
            )
        }
        for role in ("running_version", "fallback_version"):
            model = models.get(robot.get(role) or "")
            if model is None:
                continue
            gate = client.get(f"/api/models/{model['id']}/gate", headers=headers).json()
            row[role.replace("_version", "_model")] = {
                "status": model.get("status"),
                "inputs": model.get("inputs"),
                "gate_passed": gate.get("passed"),
                "gate_checks": [(c["name"], c["passed"]) for c in gate.get("checks", [])],
            }
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--setup-timeout-minutes", type=float, default=60.0)
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument(
        "--recount",
        type=Path,
        metavar="RESULTS",
        help="recount a run's board from its database, then exit",
    )
    args = parser.parse_args(argv)
    if args.recount:
        recount(args.recount)
        return 0

    var = Path(tempfile.mkdtemp(prefix="vigil-demo-hour-"))
    port = free_port()
    base_url = f"http://127.0.0.1:{port}"
    log = var / "make_run.log"
    env = {
        **os.environ,
        "VIGIL_VAR_DIR": str(var),
        "VIGIL_PORT": str(port),
        "PYTHONUNBUFFERED": "1",
    }
    for name in ("VIGIL_DATABASE_URL", "VIGIL_MODEL_STORE_DIR", "VIGIL_SECRET_KEY_FILE"):
        env.pop(name, None)  # everything in the throwaway directory
    print(f"make run's system on {var}, port {port}; log {log}", flush=True)
    started_at = datetime.now().astimezone().isoformat()
    started_utc = datetime.now(UTC).isoformat()
    begin = time.monotonic()
    with log.open("w") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "scripts.run_all"],
            cwd=ROOT,
            env=env,
            stdout=sink,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    samples = []
    try:
        timeout = args.setup_timeout_minutes * 60
        fleet_started = wait_for_line(log, "starting simulated fleet", process, timeout)
        running = wait_for_line(log, "Vigil is running", process, timeout)
        setup_s = running - begin
        print(f"running after {setup_s:.0f} s; measuring for {args.minutes:g} min", flush=True)
        client = httpx.Client(base_url=base_url, timeout=60, headers={"Origin": base_url})
        passwords = json.loads((var / "demo_passwords.json").read_text())
        end = running + args.minutes * 60
        while (now := time.monotonic()) < end:
            if process.poll() is not None:
                raise SystemExit(f"make run exited with code {process.returncode}; see {log}")
            time.sleep(min(600.0, end - now))
            nurse = sign_in(client, "nurse", passwords["nurse"])
            snapshot = board_snapshot(client, nurse, started_utc)
            samples.append(
                {
                    "minutes": round((time.monotonic() - running) / 60, 1),
                    "open_emergencies": snapshot["open_emergencies"],
                    "unresolved": snapshot["unresolved"],
                }
            )
            print(f"{samples[-1]}", flush=True)
        minutes = (time.monotonic() - running) / 60
        nurse = sign_in(client, "nurse", passwords["nurse"])
        alarms = board_alarms(client, nurse, started_utc)
        board = board_summary(alarms)
        read_at = datetime.now(UTC).isoformat()
        browser = first_card(base_url, passwords["nurse"])
        engineer = sign_in(client, "engineer", passwords["engineer"])
        models = models_run(client, engineer)
        load = os.getloadavg()
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGTERM)  # run_all stops its children as on Ctrl-C
            try:
                process.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
    log_text = log.read_text(errors="replace")
    generated = generated_falls(log_text)
    rate = 4.0  # robot_agent.source_factory.EventRates.falls_per_hour (make run's default)
    fleet_minutes = minutes + (running - fleet_started) / 60
    expected = rate * ROBOTS * fleet_minutes / 60
    # Each GENERATED transport lasts 30 s (generated_transports' duration_s): the rate applies to
    # the hours of transports, which is less than the wall clock when making them takes a while.
    transport_hours = sum(generated["transports"].values()) * 30.0 / 3600
    floor_warnings = [
        line for line in log_text.splitlines() if "WARNING" in line and "floor" in line.lower()
    ]
    newest = board["newest_open_emergency"]
    result = {
        "benchmark": "demo_hour",
        "data": "GENERATED transports (vigil.synthetic) from make run's simulated fleet; models "
        "trained on URFD (real data) plus GENERATED walking transports, gated on URFD's gold set",
        "started_at": started_at,
        "setup_s": round(setup_s, 1),
        "board_read_at": read_at,
        "measured_minutes": round(minutes, 1),
        "fleet_minutes": round(fleet_minutes, 1),
        "robots": ROBOTS,
        "configured_falls_per_robot_per_hour": rate,
        "expected_falls_at_configured_rate": round(expected, 1),
        "transport_hours": round(transport_hours, 2),
        "expected_falls_in_transport_hours": round(rate * transport_hours, 1),
        "generated": generated,
        "board": board,
        "board_in_browser": browser,
        "newest_is_first_card": newest is not None
        and browser["first_card_alarm_id"] == newest["id"],
        "open_emergencies_vs_generated_falls": [
            board["open_emergencies"],
            generated["falls_total"],
        ],
        "alarms_against_falls": alarms_against_falls(
            [a for a in alarms if a["state"] != "resolved"], generated
        ),
        "samples": samples,
        "models": models,
        "every_robot_runs_a_gated_model": bool(models)
        and all((r.get("running_model") or {}).get("gate_passed") for r in models),
        "floor_warnings_in_log": len(floor_warnings),
        "floor_warning_lines": floor_warnings[:5],
        "load_average": [round(v, 2) for v in load],
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "log": str(log),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(
        json.dumps(
            {
                k: result[k]
                for k in (
                    "expected_falls_at_configured_rate",
                    "open_emergencies_vs_generated_falls",
                    "newest_is_first_card",
                    "every_robot_runs_a_gated_model",
                    "floor_warnings_in_log",
                )
            }
        )
    )
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
