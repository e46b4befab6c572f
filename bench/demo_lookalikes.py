"""Which situations of `make run`'s simulated ward the demo's models alarm on
(`python -m bench.demo_lookalikes` -> bench/results/demo_lookalikes.json).

For each event the simulated fleet draws (routine movement, fall look-alikes, Pause situations,
falls and stumbles), `--transports` GENERATED transports made exactly as `vigil-robot simulate`
makes them (`robot_agent.source_factory.generated_transports`: 30 s, 3 people in view, the
walking and rollator robots of walking mode, seeds apart from any training seed) are played
through the simulated robot's own frame path: `robot_agent.pipeline.Pipeline` built as
`robot_agent.fleet` builds it (the model, its keypoints-only fallback, inputs keypoints, depth
and floor), every frame through `Pipeline.process` (tracker, depth, floor measures, features,
ONNX Runtime, threshold and delay filter) into an outbox. A transport "alarms" when any frame's
decision is Emergency (the backend raises an Emergency alarm on the first one).

Counts, not speed: run it under `nice`. The skeletons are GENERATED (vigil.synthetic); say so
wherever a figure from it is quoted.

    python -m bench.demo_lookalikes --model DIR --fallback DIR [--label NAME] [--transports 8]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "results" / "demo_lookalikes.json"
#: The fleet's events (robot_agent.source_factory) per kind.
KINDS = {
    "routine": ("turning", "gesturing", "standing"),
    "lookalike": ("bending", "sitting_down", "lying_down_deliberately"),
    "pause": ("too_far_away",),
    "emergency": ("fall", "sitting_on_floor_after_fall", "stumbling"),
}
LOCOMOTIONS = ("walking", "rollator")  # make run's walking robots (robot_agent.fleet._locomotion)
SEED = 70_000  # far from the training seeds (worker.training.generated) and the fleet's


def play(
    model_dir: Path,
    fallback_dir: Path | None,
    event: str,
    locomotion: str,
    seed: int,
    workdir: Path,
) -> dict:
    from robot_agent.outbox import Outbox
    from robot_agent.pipeline import Pipeline
    from robot_agent.source_factory import generated_transports
    from vigil.classes import Decision, TransportMode
    from vigil.runtime import FrameClassifier
    from vigil.taxonomy import DEFAULT_TAXONOMY

    (plan,) = generated_transports(seed=seed, locomotion=locomotion, events=[event], count=1)
    pipeline = Pipeline(
        Outbox(workdir / f"{event}-{locomotion}-{seed}.sqlite"),
        TransportMode.WALKING,
        FrameClassifier.from_dir(model_dir),
        fallback=FrameClassifier.from_dir(fallback_dir) if fallback_dir else None,
        available_inputs=["keypoints", "depth", "floor"],  # as robot_agent.fleet
    )
    pipeline.start_transport(f"bench-{seed}", time.time(), plan.patient, plan.location, plan.fps)
    first, truth_first, frames = None, None, 0
    for observation in plan.observations:
        result = pipeline.process(observation)
        if result.decision == Decision.EMERGENCY and first is None:
            first = observation.timestamp
        truth = observation.truth
        if (
            truth_first is None
            and truth is not None
            and (DEFAULT_TAXONOMY.decision(truth, TransportMode.WALKING) == Decision.EMERGENCY)
        ):
            truth_first = observation.timestamp
        frames += 1
    pipeline.end_transport(time.time())
    pipeline.outbox.close()
    return {
        "alarmed": first is not None,
        "first_emergency_s": first,
        "truth_emergency_s": truth_first,
        "frames": frames,
    }


def measure(model_dir: Path, fallback_dir: Path | None, transports: int) -> dict:
    from vigil.model_file import read_manifest

    manifest, _ = read_manifest(model_dir / "manifest.json")
    per_event: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for kind, events in KINDS.items():
            for event in events:
                runs = []
                for i in range(transports):
                    locomotion = LOCOMOTIONS[i % len(LOCOMOTIONS)]
                    if event == "lying_down_deliberately" and locomotion == "rollator":
                        locomotion = "walking"  # the generator has it for walking only
                    if event == "sitting_down" and locomotion == "rollator":
                        locomotion = "walking"
                    runs.append(
                        play(model_dir, fallback_dir, event, locomotion, SEED + i, Path(tmp))
                    )
                alarmed = sum(r["alarmed"] for r in runs)
                per_event[event] = {
                    "kind": kind,
                    "transports": len(runs),
                    "alarmed": alarmed,
                    "alarmed_share": round(alarmed / len(runs), 3),
                }
                print(f"{manifest.version} {event:28s} {alarmed}/{len(runs)}", flush=True)
    false_kinds = ("routine", "lookalike", "pause")
    return {
        "model": manifest.version,
        "model_inputs": list(manifest.inputs),
        "training_data": manifest.metrics.get("dataset"),
        "threshold": manifest.threshold,
        "delay_ms": manifest.delay_ms,
        "events": per_event,
        "false_alarm_transports": sum(
            v["alarmed"] for v in per_event.values() if v["kind"] in false_kinds
        ),
        "non_fall_transports": sum(
            v["transports"] for v in per_event.values() if v["kind"] in false_kinds
        ),
        "alarmed_fall_transports": sum(
            v["alarmed"] for v in per_event.values() if v["kind"] == "emergency"
        ),
        "fall_transports": sum(
            v["transports"] for v in per_event.values() if v["kind"] == "emergency"
        ),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, required=True)
    parser.add_argument("--fallback", type=Path, default=None)
    parser.add_argument("--label", default=None, help="key of this run in the results file")
    parser.add_argument("--transports", type=int, default=8, help="per event")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    result = measure(args.model, args.fallback, args.transports)
    data = json.loads(args.out.read_text()) if args.out.exists() else {}
    data.update(
        {
            "benchmark": "demo_lookalikes",
            "data": "GENERATED transports (vigil.synthetic) as make run's simulated fleet makes "
            "them, through the simulated robot's frame path (robot_agent.pipeline.Pipeline)",
        }
    )
    runs = data.setdefault("runs", {})
    runs[args.label or result["model"]] = {
        **result,
        "transports_per_event": args.transports,
        "seconds": round(time.perf_counter() - started, 1),
        "measured_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "events"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
