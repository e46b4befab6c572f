"""`make run`: migrate, seed demo users and robots, train (first run) and register both walking
models (depth/floor and keypoints-only), then start a simulated hospital Alert Manager (phones,
IHE PCD ACM), the backend, the worker and a simulated fleet of 3 robots; once the robots said
what they can feed, each gets a model it can feed. Ctrl-C stops every child process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Everything `make run` writes (database, secret key, models, tokens, outboxes); VIGIL_VAR_DIR
#: moves it elsewhere, e.g. a throwaway directory (bench/demo_hour.py).
VAR = Path(os.environ.get("VIGIL_VAR_DIR") or ROOT / "var").resolve()
PY = sys.executable
HOST, PORT = "127.0.0.1", int(os.environ.get("VIGIL_PORT", "8000"))
MODEL_DIR = VAR / "models" / "default-walking"  # feature set "full": keypoints + floor measures
KEYPOINTS_MODEL_DIR = VAR / "models" / "keypoints-walking"  # every walking robot's fallback
ROBOTS = 3
#: The simulated ward's pace per robot (robot_agent.config: falls_per_hour, pauses_per_hour,
#: lookalikes_per_hour); VIGIL_FALLS_PER_HOUR etc. override the defaults.
FLEET_RATES = [
    arg
    for flag, name in (
        ("--falls-per-hour", "VIGIL_FALLS_PER_HOUR"),
        ("--pauses-per-hour", "VIGIL_PAUSES_PER_HOUR"),
        ("--lookalikes-per-hour", "VIGIL_LOOKALIKES_PER_HOUR"),
    )
    if os.environ.get(name)
    for arg in (flag, os.environ[name])
]
TOKENS = VAR / "robot_tokens.json"
#: The local Alert Manager simulator (phones over IHE PCD ACM): Vigil sends it ORU^R40 and it
#: answers with ORA^R41 dispositions on Vigil's listener. Setting VIGIL_ALERT_MANAGER points the
#: backend at a real one instead and no simulator starts. VIGIL_DEMO_PHONE_ACCEPT_S makes the
#: simulated phone accept (and so acknowledge) each alert after that many seconds.
ALERT_MANAGER = os.environ.get("VIGIL_DEMO_ALERT_MANAGER", "127.0.0.1:2575")
ALERT_STATUS_LISTEN = os.environ.get("VIGIL_DEMO_ALERT_STATUS_LISTEN", "127.0.0.1:2576")


def fleet_banner() -> str:
    """The simulated fleet's start-up line, with the rates in force (the robot agent's settings,
    which the fleet reads from the same environment), not the defaults'."""
    from robot_agent.config import AgentSettings

    rates = AgentSettings()
    return (
        f"simulated fleet of {ROBOTS} robots (generated transports, per robot per hour: "
        f"{rates.falls_per_hour:g} falls, {rates.pauses_per_hour:g} Pause situations, "
        f"{rates.lookalikes_per_hour:g} look-alikes)"
    )


def use_var_dir() -> None:
    """Point every child's settings at VAR when VIGIL_VAR_DIR moved it (settings given in the
    environment stay as they are)."""
    if not os.environ.get("VIGIL_VAR_DIR"):
        return  # the settings' own defaults are ROOT/var already (and a .env file may set them)
    for name, value in (
        ("VIGIL_DATABASE_URL", f"sqlite:///{VAR / 'vigil.db'}"),
        ("VIGIL_SECRET_KEY_FILE", VAR / "secret_key"),
        ("VIGIL_MODEL_STORE_DIR", VAR / "models"),
        ("VIGIL_LABELLING_MODEL_DIR", MODEL_DIR),
        ("VIGIL_ARCHIVE_DIR", VAR / "archive"),
        ("VIGIL_ROBOT_MODELS_DIR", VAR / "robot-models"),
    ):
        os.environ.setdefault(name, str(value))


def alert_manager_simulator() -> list[str] | None:
    """The simulator's arguments, or None when the environment names a real Alert Manager."""
    if os.environ.get("VIGIL_ALERT_MANAGER"):
        return None
    os.environ["VIGIL_ALERT_MANAGER"] = ALERT_MANAGER
    os.environ.setdefault("VIGIL_ALERT_STATUS_LISTEN", ALERT_STATUS_LISTEN)
    from backend.demo import DEMO_WARD

    arguments = ["-m", "scripts.alert_manager_simulator", "--listen", ALERT_MANAGER]
    arguments += ["--vigil", os.environ["VIGIL_ALERT_STATUS_LISTEN"]]
    arguments += ["--ward-phone", f"{DEMO_WARD}=Anna Berg"]
    if accept_after := os.environ.get("VIGIL_DEMO_PHONE_ACCEPT_S"):
        arguments += ["--accept-after", accept_after]
    return arguments


def step(title: str, *args: str) -> None:
    print(f"==> {title}", flush=True)
    subprocess.run([PY, *args], cwd=ROOT, check=True)


def start(name: str, *args: str) -> subprocess.Popen:
    print(f"==> starting {name}", flush=True)
    return subprocess.Popen([PY, *args], cwd=ROOT, start_new_session=True)


def wait_for_backend(timeout_s: float = 60) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"http://{HOST}:{PORT}/api/health", timeout=1):
                return
        except OSError:
            time.sleep(0.3)
    raise SystemExit(f"backend did not answer on http://{HOST}:{PORT} within {timeout_s:.0f} s")


def stop(children: list[subprocess.Popen]) -> None:
    for child in children:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGTERM)
    deadline = time.monotonic() + 10
    for child in children:
        try:
            child.wait(max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)


def model_is_current(directory: Path = MODEL_DIR, demo: bool = False) -> bool:
    """A model exists there and was trained with this code's features on URFD's training split
    only (its manifest names its training recordings, none of them gold), and, for `demo`, plus
    the GENERATED walking transports: `train-default --with-generated`."""
    from vigil.datasets import urfd
    from vigil.features import FEATURE_VERSION
    from vigil.model_file import read_manifest

    try:
        manifest, _ = read_manifest(directory / "manifest.json")
    except (OSError, ValueError):
        return False
    if demo and manifest.metrics.get("dataset") != "urfd+generated":
        return False
    trained_on = manifest.training_recordings
    if not trained_on or set(trained_on) & set(urfd.split()[1]):
        return False  # trained before the split was kept, or on the gold set: train again
    return manifest.feature_version == FEATURE_VERSION


def default_model_is_current() -> bool:
    return model_is_current(MODEL_DIR)


def train_missing_models() -> None:
    """Train the models that are missing or stale, side by side (the machine has two cores)."""
    jobs = []
    # The demo's robots stream GENERATED patients: both models learn from URFD (real) plus
    # GENERATED walking transports (turning, lying on a bed, stumbling... that URFD lacks); the
    # promotion gate still judges them on the URFD gold set, and their manifests say generated.
    if not model_is_current(MODEL_DIR, demo=True):
        train = [
            "-m",
            "worker.training.cli",
            "train-default",
            "--out",
            str(MODEL_DIR),
            "--with-generated",
        ]
        jobs.append(
            (
                "the default walking model (depth/floor measures) on URFD + GENERATED "
                "walking transports",
                train,
            )
        )
    if not model_is_current(KEYPOINTS_MODEL_DIR, demo=True):
        jobs.append(
            (
                "the keypoints-only walking model on URFD + GENERATED walking transports",
                [
                    "-m",
                    "worker.bootstrap",
                    "train-keypoints",
                    "--out",
                    str(KEYPOINTS_MODEL_DIR),
                    "--with-generated",
                ],
            )
        )
    running = []
    for title, args in jobs:
        print(f"==> training {title} (first run, or after a feature change)", flush=True)
        running.append((title, subprocess.Popen([PY, *args], cwd=ROOT)))
    for title, process in running:
        if process.wait() != 0:
            raise SystemExit(f"training {title} failed (exit code {process.returncode})")


def _terminate(signum, frame) -> None:
    raise KeyboardInterrupt  # SIGTERM stops the children exactly as Ctrl-C does


def main() -> int:
    signal.signal(signal.SIGTERM, _terminate)
    VAR.mkdir(parents=True, exist_ok=True)
    use_var_dir()
    step("applying database migrations", "-m", "backend.cli", "migrate")
    step(
        "creating demo users and robots",
        "-m",
        "backend.cli",
        "seed-demo",
        "--robots",
        str(ROBOTS),
        "--tokens-file",
        str(TOKENS),
        "--passwords-file",
        str(VAR / "demo_passwords.json"),
    )
    train_missing_models()
    models = ["--floor-model", str(MODEL_DIR), "--keypoints-model", str(KEYPOINTS_MODEL_DIR)]
    step(
        "model registry: URFD training and gold recordings, both walking models registered "
        "and promoted to robots that can feed them (idempotent)",
        "-m",
        "worker.bootstrap",
        "demo",
        *models,
    )
    children: list[subprocess.Popen] = []
    try:
        simulator = alert_manager_simulator()
        if simulator:
            children.append(start("alert manager simulator (phones, IHE PCD ACM)", *simulator))
        children.append(
            start("backend", "-m", "backend.cli", "serve", "--host", HOST, "--port", str(PORT))
        )
        wait_for_backend()
        children.append(start("worker", "-m", "worker.cli", "run"))
        children.append(
            start(
                fleet_banner(),
                "-m",
                "robot_agent.cli",
                "simulate",
                "--backend",
                f"ws://{HOST}:{PORT}/ws/robot",
                "--robots",
                str(ROBOTS),
                "--tokens-file",
                str(TOKENS),
                "--outbox-dir",
                str(VAR / "robot-outbox"),
                # No local model: a robot runs only what the registry assigned it through the
                # promotion gate; until then it streams the generator's ground truth, marked
                # model_version "generated-ground-truth". Rates: --falls-per-hour etc.
                *FLEET_RATES,
            )
        )
        # The robots' hellos said what they feed: the floor model goes to those that can.
        step(
            "promoting the depth/floor model to the robots that feed floor measures",
            "-m",
            "worker.bootstrap",
            "demo",
            *models,
            "--promote-only",
            "--wait-for-robots",
            str(ROBOTS),
            "--timeout",
            "30",
        )
        print(
            f"\nVigil is running: open http://{HOST}:{PORT} and sign in as nurse "
            "(password printed above). Ctrl-C stops everything.\n",
            flush=True,
        )
        while True:
            for child in children:
                if child.poll() is not None:
                    print(f"a child process exited with code {child.returncode}; stopping")
                    return 1
            time.sleep(0.5)
    except KeyboardInterrupt:
        print("\nstopping…")
        return 0
    finally:
        stop(children)


if __name__ == "__main__":
    sys.exit(main())
