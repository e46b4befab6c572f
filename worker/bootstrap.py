"""First-run registry contents for `make run`: URFD (real data) split into training and gold
recordings, the default model registered, and one retrain job queued on the training split.

`python -m worker.bootstrap demo` (what `make run` calls) registers both walking models, the
floor model (feature set "full") and the keypoints-only one, synchronously with their gold-set
evaluation, and promotes them through the registry's rollout service so every robot runs a model
it can feed and walking mode has its keypoints-only fallback in production."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.jobs import queue
from backend.labelling.importers.urfd import import_urfd
from backend.models.jobs import Job, JobKind
from backend.models.registry import ModelVersion
from vigil.datasets import urfd
from worker.training.specs import DEFAULT, KEYPOINTS_DEFAULT

# Every fifth fall and ADL recording is held out as the gold set (6 falls, 8 daily activities):
# the importer's split (vigil.datasets.urfd.is_gold), which the demo's models train on too.
GOLD = urfd.split()[1]


def urfd_split() -> tuple[list[str], list[str]]:
    return urfd.split()


def bootstrap(session: Session, default_model_dir: Path | None, urfd_dir=None) -> list[str]:
    """Idempotent; returns what it did."""
    done = []
    train, gold = urfd_split()
    if (urfd.default_dir() if urfd_dir is None else Path(urfd_dir)).exists():
        # The one URFD importer, as seed-demo runs it: what seed-demo imported is skipped, and
        # a split an admin changed stays (new videos get the gold split, urfd.is_gold).
        import_urfd(session, urfd_dir, train + gold)
        add_floor_measures(session, train + gold, urfd_dir)
        done.append(f"URFD: {len(train)} training and {len(gold)} gold recordings")
    has_models = session.scalar(select(func.count()).select_from(ModelVersion))
    has_jobs = session.scalar(select(func.count()).select_from(Job))
    if not has_models and not has_jobs:
        if default_model_dir is not None and (default_model_dir / "manifest.json").exists():
            queue.enqueue(session, JobKind.REGISTER, {"path": str(default_model_dir)})
            done.append(f"queued: register {default_model_dir}")
        queue.enqueue(session, JobKind.RETRAIN, {"spec": DEFAULT.name})
        done.append(f"queued: retrain {DEFAULT.name} on the training split")
    return done


def add_floor_measures(session: Session, names: list[str], urfd_dir=None) -> int:
    """Give the frames of the imported URFD recordings URFD's own floor measures where they
    have none (databases made before the URFD importer stored them), so that a model
    that needs floor measures is trained and judged on the gold set with them; idempotent.
    Returns the recordings filled."""
    from sqlalchemy import bindparam, update

    from backend.models.videos import Frame
    from vigil.skeleton import encode_floor

    bare = _videos_without_floor(session, names)
    if not bare:
        return 0
    statement = (
        update(Frame.__table__)
        .where(Frame.__table__.c.video_id == bindparam("v"))
        .where(Frame.__table__.c.index == bindparam("i"))
        .values(floor=bindparam("f"))
    )
    for sequence in urfd.load(urfd_dir, list(bare)):
        rows = [
            {"v": bare[sequence.name], "i": i, "f": encode_floor(floor)}
            for i, floor in enumerate(sequence.floor)
        ]
        session.execute(statement, [r for r in rows if r["f"] is not None])
    return len(bare)


def _videos_without_floor(session: Session, names: list[str]) -> dict[str, int]:
    from backend.models.videos import Frame, Video

    with_floor = select(Frame.video_id).where(Frame.floor.is_not(None)).distinct()
    return dict(
        session.execute(
            select(Video.name, Video.id).where(
                Video.name.in_(names), Video.source == "urfd", Video.id.not_in(with_floor)
            )
        ).all()
    )


# --- the demo of `make run`: a keypoints-only and a floor model, promoted to robots that can
# feed them ---------------------------------------------------------------------------------

#: The walking mode's keypoints-only model (no floor measures): every walking robot's fallback
#: and the model of robots without a calibrated depth camera; the registry's
#: rf-keypoints-default (worker.training.specs), one configuration.
KEYPOINTS_SPEC = KEYPOINTS_DEFAULT
DEMO_ENGINEER = "engineer"


def train_keypoints(out: Path, urfd_dir: Path | None = None, with_generated: bool = False) -> None:
    """Train KEYPOINTS_SPEC on URFD's training split as train-default trains the default model
    (real data; with `with_generated` plus GENERATED walking transports, as train-default
    --with-generated)."""
    from worker.training.cli import train_demo_model

    manifest = train_demo_model(KEYPOINTS_SPEC, out, urfd_dir, with_generated, stride=3)
    print(f"  inputs {manifest.inputs}")


def register_model_dir(session: Session, model_dir: Path, store_dir: Path) -> ModelVersion:
    """Register a model directory and evaluate it on the gold set, as the register job does
    (here synchronously, so the demo can promote it at once); the registered version if its
    version is registered already."""
    from vigil.model_file import load_classifier, read_manifest
    from worker.jobs.common import gold_evaluation
    from worker.registration import register, store_path

    manifest, _ = read_manifest(model_dir)
    existing = session.scalars(
        select(ModelVersion).where(ModelVersion.version == manifest.version)
    ).first()
    if existing is not None:
        return existing
    classifier = load_classifier(model_dir)
    model = register(
        session,
        model_dir,
        store_dir,
        lineage={
            "started_by": {"user_id": None, "username": "make run", "job_id": None},
            "source": str(model_dir),
            "parent": None,
            "hyperparameters": manifest.metrics.get("params"),
        },
    )
    model.metrics = gold_evaluation(
        session, classifier, store_path(store_dir, model.version), manifest.mode
    )
    return model


def _signer(session: Session):
    from backend.models.users import Role, User

    user = session.scalars(select(User).where(User.username == DEMO_ENGINEER)).first()
    return (
        user
        or session.scalars(
            select(User).where(User.role.in_([Role.ENGINEER, Role.ADMIN])).order_by(User.id)
        ).first()
    )


def promote_demo_models(
    session: Session, floor: ModelVersion | None, keypoints: ModelVersion, settings=None
) -> list[str]:
    """Give every robot a model it can feed, through the registry's own promotion (gate and
    sign-off by the demo engineer; one deployment per robot, so no canary waits):

    - the keypoints-only model first, to every robot, while the mode has no keypoints-only
      model in production (it is every robot's fallback), and to any robot without a model or
      with a model it cannot feed;
    - the floor model to each robot whose last hello said it feeds floor measures, unless the
      robot runs another model already (an engineer's choice is kept).
    """
    from backend.models.registry import DeploymentScope
    from backend.models.robots import Robot
    from backend.registry import capability, rollout
    from backend.registry.gate import gate_report
    from backend.settings import Settings

    settings = settings or Settings()
    signer = _signer(session)
    if signer is None:
        return ["no engineer account: demo models not promoted (run backend.cli seed-demo)"]
    done: list[str] = []

    def promote(model: ModelVersion, robot: Robot) -> bool:
        gate = gate_report(model, settings.gate_false_alarm_budget, settings.gate_latency_ms)
        try:
            deployment, _ = rollout.promote(
                session,
                model,
                signer,
                DeploymentScope.ROBOT,
                robot.id,
                gate,
                comment="make run: a model this robot can feed",
                require_second_approver=settings.require_second_approver,
            )
        except rollout.RolloutError as error:
            done.append(f"{model.version} not promoted to {robot.id}: {error}")
            return False
        session.flush()
        done.append(f"promoted {model.version} to {robot.id} ({deployment.status})")
        return True

    robots = list(session.scalars(select(Robot).order_by(Robot.id)))
    for number, robot in enumerate(robots):
        current = (
            session.get(ModelVersion, robot.assigned_model_id) if robot.assigned_model_id else None
        )
        cannot_feed = current is not None and bool(capability.missing_for(robot, current))
        no_fallback = capability.fallback_model(session, keypoints.mode) is None
        if (current is None or cannot_feed or (no_fallback and number == 0)) and (
            current is None or current.id != keypoints.id
        ):
            promote(keypoints, robot)  # also the mode's fallback before any floor model
        feeds_floor = floor is not None and not capability.missing_for(robot, floor)
        if feeds_floor and (current is None or cannot_feed or current.id == keypoints.id):
            promote(floor, robot)
    if floor is not None and not any(not capability.missing_for(robot, floor) for robot in robots):
        done.append(
            f"{floor.version} stays a candidate: no robot said it feeds "
            f"{', '.join(capability.model_needs(floor))}"
        )
    return done


def wait_for_hellos(session_factory, since, robots: int, timeout_s: float) -> int:
    """Wait until `robots` robots said hello after `since` (they report their inputs then)."""
    import time

    from sqlalchemy import func

    from backend.models.robots import Robot

    deadline = time.monotonic() + timeout_s
    while True:
        with session_factory() as session:
            seen = session.scalar(
                select(func.count()).select_from(Robot).where(Robot.last_seen_at >= since)
            )
        if seen >= robots or time.monotonic() > deadline:
            return seen
        time.sleep(0.5)


def main(argv: list[str] | None = None) -> int:
    """python -m worker.bootstrap train-keypoints --out DIR
    python -m worker.bootstrap demo --floor-model DIR --keypoints-model DIR
        [--promote-only --wait-for-robots N --timeout S]"""
    import argparse

    from backend.db import make_engine, make_session_factory, transaction
    from backend.models._types import utcnow
    from worker.settings import WorkerSettings

    parser = argparse.ArgumentParser(prog="python -m worker.bootstrap", description=main.__doc__)
    parser.add_argument("--urfd-dir", type=Path, default=None, help="default: $VIGIL_URFD_DIR")
    commands = parser.add_subparsers(dest="command", required=True)
    train = commands.add_parser("train-keypoints", help="train the keypoints-only walking model")
    train.add_argument("--out", type=Path, required=True)
    train.add_argument(
        "--with-generated", action="store_true", help="add GENERATED walking transports (make run)"
    )
    demo = commands.add_parser("demo", help="URFD split, both models registered and promoted")
    demo.add_argument("--floor-model", type=Path, required=True)
    demo.add_argument("--keypoints-model", type=Path, required=True)
    demo.add_argument("--promote-only", action="store_true", help="models are registered")
    demo.add_argument(
        "--wait-for-robots",
        type=int,
        default=0,
        help="first wait until this many robots said hello",
    )
    demo.add_argument("--timeout", type=float, default=20.0)
    args = parser.parse_args(argv)
    if args.command == "train-keypoints":
        train_keypoints(args.out, args.urfd_dir, args.with_generated)
        return 0
    from vigil.model_file import read_manifest

    settings = WorkerSettings()
    started = utcnow()
    engine = make_engine(settings.database_url)
    factory = make_session_factory(engine)
    try:
        if args.wait_for_robots:
            seen = wait_for_hellos(factory, started, args.wait_for_robots, args.timeout)
            print(f"{seen} of {args.wait_for_robots} robots said hello")
        with transaction(factory) as session:
            lines = [] if args.promote_only else bootstrap(session, None, args.urfd_dir)
            if args.promote_only:
                versions = [
                    read_manifest(d)[0].version for d in (args.floor_model, args.keypoints_model)
                ]
                floor, keypoints = (
                    session.scalars(select(ModelVersion).where(ModelVersion.version == v)).first()
                    for v in versions
                )
                if keypoints is None:
                    print("the keypoints-only model is not registered: nothing promoted")
                    return 1
            else:
                floor = register_model_dir(session, args.floor_model, settings.model_store_dir)
                keypoints = register_model_dir(
                    session, args.keypoints_model, settings.model_store_dir
                )
                lines.append(
                    f"registered {floor.version} (needs "
                    f"{', '.join(floor.manifest.get('inputs') or [])}) and "
                    f"{keypoints.version} (keypoints only)"
                )
            lines += promote_demo_models(session, floor, keypoints)
        for line in lines:
            print(line)
    finally:
        engine.dispose()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
