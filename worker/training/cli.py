"""vigil-train: train, evaluate and export detection models.

  python -m worker.training.cli train-default --out DIR   # the default walking model, < 1 min,
      # on URFD's training split (its gold set left out for the promotion gate)
      [--with-generated]   # URFD plus GENERATED walking transports (make run's demo robots)
  python -m worker.training.cli train --out DIR [--models svm-paper,svm,mlp,rf,gbt,tcn]
      [--mode walking|wheelchair|combined]   # wheelchair/combined train on GENERATED data

Writes DIR/<mode>/report.json, report.md, plots/*.png and models/<name>/{model.onnx,manifest.json}.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from vigil.datasets import urfd
from vigil.model_file import ModelManifest
from worker.training.cross_validation import select
from worker.training.data import from_urfd
from worker.training.estimators import ModelSpec
from worker.training.publish import publish
from worker.training.specs import DEFAULT, SPECS
from worker.training.trainers import SklearnTrainer

#: What train-default trains: the registry's rf-default (worker.training.specs).
DEFAULT_SPEC = DEFAULT


#: `--with-generated`: GENERATED walking and rollator transports added to URFD for `make run`'s
#: demo model, whose robots stream generated patients: every event of the generator once per
#: repeat (turning, lying on a bed, sitting down, bending, stumbling, falls...), 8 s each.
GENERATED_REPEATS = 2
GENERATED_SEED = 5000  # apart from bench/demo_lookalikes.py's seeds and the fleet's


def training_data(urfd_dir: Path | None, with_generated: bool, repeats: int | None = None):
    """URFD's training split (real; its gold set, `vigil.datasets.urfd.split`, stays out for the
    gate to judge on), or that plus GENERATED walking transports (depth removed, so the model
    needs what a URFD model needs); (data, the manifest's metrics). The rows come from the one
    builder (`build_rows`, URFD file source), as the retrain job's from the database."""
    train, gold = urfd.split()
    data = from_urfd(urfd_dir, names=train)
    metrics = {
        "dataset": "urfd",
        "note": "threshold and delay chosen on 5-fold OOF scores",
        "urfd_training_recordings": len(train),
        "urfd_gold_recordings_left_out": gold,
    }
    if with_generated:
        from vigil.classes import TransportMode
        from worker.training.data import concatenate
        from worker.training.generated import generated_frames

        generated = generated_frames(
            TransportMode.WALKING, repeats or GENERATED_REPEATS, GENERATED_SEED, depth=False
        )
        data = concatenate(data, generated)
        metrics = {
            **metrics,
            "dataset": "urfd+generated",
            "generated_sequences": len(generated.names),
            "note": "URFD (real) plus GENERATED walking/rollator transports (vigil.synthetic, "
            "look-alikes and falls URFD lacks) for make run's simulated robots; threshold and "
            "delay chosen on 5-fold OOF scores of both; gate on the URFD gold set",
        }
    return data, metrics


def train_demo_model(
    spec: ModelSpec,
    out: Path,
    urfd_dir: Path | None,
    with_generated: bool = False,
    repeats: int | None = None,
    stride: int = 2,
) -> ModelManifest:
    """Train `spec` as `make run` trains its demo models (`training_data`: URFD's training
    split, optionally with GENERATED transports), 5 folds, and write the model to `out`; its
    manifest names the recordings it was trained on."""
    start = time.perf_counter()
    data, metrics = training_data(urfd_dir, with_generated, repeats)
    trainer = SklearnTrainer(spec)
    with threadpool_limits(limits=1):
        selected = select(trainer, data, np.arange(len(data.names)), n_inner=5, stride=stride)
    manifest = publish(trainer, selected, data, out, metrics=metrics)
    print(
        f"wrote {out} ({manifest.name}, threshold {manifest.threshold:.3f}, "
        f"delay {manifest.delay_ms} ms; {len(data.names)} training recordings, URFD gold set "
        f"left out) in {time.perf_counter() - start:.1f} s"
    )
    return manifest


def train_default(
    out: Path, urfd_dir: Path | None, with_generated: bool = False, repeats: int | None = None
) -> None:
    train_demo_model(DEFAULT_SPEC, out, urfd_dir, with_generated, repeats, stride=2)


def make_trainers(names: list[str]) -> list[SklearnTrainer]:
    """The trainers of registered specs by name (the window model `tcn` is one of them)."""
    unknown = [name for name in names if name not in SPECS]
    if unknown:
        known = ", ".join(SPECS)
        raise ValueError(f"--models: unknown model {unknown[0]!r} (known: {known})")
    return [SklearnTrainer(SPECS[name]) for name in names]


#: The benchmark's models: the registry's benchmarked grids, the window model among them.
ALL_MODELS = ",".join(SPECS.benchmarked())
MULTI = "mlp,rf,tcn"


def train(out: Path, models: str, mode: str, urfd_dir: Path | None, folds: int) -> dict:
    from worker.training.run import table_row, train_all

    names = [m.strip() for m in models.split(",") if m.strip()]
    if mode != "walking" and any(n.startswith("svm") for n in names):
        # Scores are sigmoid(decision) for the binary SVM; a calibrated three-class SVM head is
        # not implemented, so three-class modes use the other families.
        raise ValueError(f"--models: SVM models are binary (walking mode only), not {mode}")
    trainers = make_trainers(names)
    if mode == "walking":
        data = from_urfd(urfd_dir)
    else:
        from worker.training.generated import generated_frames

        data = generated_frames(mode)
    report = train_all(data, trainers, out / mode, n_folds=folds)
    for row in report["models"]:
        print(" | ".join(table_row(row)))
    print(f"best: {report['best']}; report: {out / mode / 'report.md'}")
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="vigil-train", description=__doc__.splitlines()[0])
    parser.add_argument("--urfd-dir", type=Path, default=None, help="default: $VIGIL_URFD_DIR")
    sub = parser.add_subparsers(dest="command", required=True)
    default = sub.add_parser("train-default", help="train the default walking model (fast)")
    default.add_argument("--out", type=Path, required=True, help="model directory to write")
    default.add_argument(
        "--with-generated", action="store_true", help="add GENERATED walking transports (make run)"
    )
    default.add_argument(
        "--generated-repeats", type=int, default=None, help="transports per generated event"
    )
    full = sub.add_parser("train", help="evaluate, retrain and export all models with reports")
    full.add_argument("--out", type=Path, required=True, help="output directory")
    full.add_argument(
        "--models", default=None, help=f"comma separated (walking: {ALL_MODELS}; else {MULTI})"
    )
    full.add_argument("--mode", default="walking", choices=["walking", "wheelchair", "combined"])
    full.add_argument("--folds", type=int, default=5)
    args = parser.parse_args(argv)
    try:
        if args.command == "train-default":
            train_default(args.out, args.urfd_dir, args.with_generated, args.generated_repeats)
        elif args.command == "train":
            if args.folds < 2:
                raise ValueError("--folds must be at least 2")
            models = args.models or (ALL_MODELS if args.mode == "walking" else MULTI)
            train(args.out, models, args.mode, args.urfd_dir, args.folds)
    except (FileNotFoundError, ValueError) as error:
        print(f"vigil-train: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
