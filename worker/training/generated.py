"""FrameData from GENERATED transports (vigil.synthetic) for the wheelchair and combined modes,
which URFD cannot provide, and the walking situations URFD lacks (turning, lying on a bed,
stumbling, a rollator: `make run`'s demo model, `worker.training.cli train-default
--with-generated`). Every figure and model made from it is labelled generated."""

from __future__ import annotations

import hashlib

import numpy as np

from vigil.classes import MODE_CLASSES, TransportMode
from vigil.observation import Observation
from vigil.skeleton import SkeletonFrame
from vigil.synthetic import EVENTS_BY_LOCOMOTION, GeneratedTransport, Locomotion, generate_transport
from worker.training.data import FrameData, Recording, build_rows

LOCOMOTIONS: dict[TransportMode, tuple[Locomotion, ...]] = {
    TransportMode.WHEELCHAIR: (Locomotion.WHEELCHAIR,),
    TransportMode.COMBINED: (Locomotion.WHEELCHAIR, Locomotion.WALKING, Locomotion.ROLLATOR),
    TransportMode.WALKING: (Locomotion.WALKING, Locomotion.ROLLATOR),
}


def generate_for_mode(
    mode: TransportMode | str, repeats: int = 5, seed: int = 0, duration_s: float = 8.0
) -> list[GeneratedTransport]:
    """One short transport per (locomotion, event, repeat): each event of the mode `repeats`
    times, so every sequence holds one situation between stretches of normal activity."""
    mode = TransportMode(mode)
    transports = []
    for locomotion in LOCOMOTIONS[mode]:
        for event in EVENTS_BY_LOCOMOTION[locomotion]:
            for _ in range(repeats):
                transports.append(
                    generate_transport(
                        locomotion,
                        seed=seed + len(transports),
                        duration_s=duration_s,
                        events=[event],
                    )
                )
    return transports


def patient_arrays(transport: GeneratedTransport):
    """Keypoints (n, 25, 3), depth (n, 25), usable (n,), floor measures (n, 3); frames where the
    patient is not seen are empty (all keypoints missing), as a pose estimator would report
    nobody."""
    sequence = transport.patient_sequence()
    usable = np.array([frame is not None for frame in transport.patient_frames])
    return sequence.keypoints, sequence.depth, usable, sequence.floor


DEFAULT_REPEATS = {TransportMode.WHEELCHAIR: 4, TransportMode.COMBINED: 2, TransportMode.WALKING: 2}


def generated_recordings(
    mode: TransportMode | str, repeats: int | None = None, seed: int = 0, depth: bool = True
) -> tuple[list[Recording], str]:
    """The generated source: each transport's patient alone in view (the bystanders are the
    tracker's part: bench-robot), targets from the generator's decisions for `mode`.

    depth False: the frames carry no depth at the keypoints (their floor measures stay, made
    by the generator's camera), as URFD's: a model trained on both cannot tell them apart by
    `has_depth`, and needs the inputs a URFD model needs (keypoints, floor)."""
    mode = TransportMode(mode)
    repeats = repeats or DEFAULT_REPEATS[mode]
    classes = MODE_CLASSES[mode]
    digest = hashlib.sha256()
    recordings = []
    for transport in generate_for_mode(mode, repeats, seed):
        recordings.append(_recording(transport, mode, classes, depth))
        digest.update(transport.patient_sequence().keypoints.tobytes())
    return recordings, digest.hexdigest()


def _recording(transport: GeneratedTransport, mode: TransportMode, classes, depth: bool):
    keypoints, depths, usable, floor = patient_arrays(transport)
    if not depth:
        depths = np.full_like(depths, np.nan)
    timestamps = np.arange(transport.n_frames) / transport.fps
    observations = tuple(
        Observation(
            float(ts),
            [SkeletonFrame(keypoints[t], depths[t], float(ts), floor[t])] if usable[t] else [],
            t,
        )
        for t, ts in enumerate(timestamps)
    )
    target = np.array([classes.index(d) for d in transport.decisions(mode)])
    name = f"gen-{transport.locomotion.value}-{'+'.join(transport.events)}-{transport.seed:03d}"
    return Recording(name, observations, target, generated=True)


def generated_frames(
    mode: TransportMode | str, repeats: int | None = None, seed: int = 0, depth: bool = True
) -> FrameData:
    """Training rows of generated transports (the one builder, `build_rows`, fed by the
    generated source); see `generated_recordings`."""
    recordings, digest = generated_recordings(mode, repeats, seed, depth)
    return build_rows(recordings, mode, digest)


#: The GENERATED hard negatives of issue #34's keypoints-only attempt: a walking patient lying
#: down deliberately on a bed 0.55-0.8 m up (vigil.synthetic's `lying_down_deliberately`), what
#: URFD's daily activities adl-10 and adl-11 do and where a keypoints-only model alarms.
BED_EVENT = "lying_down_deliberately"
BED_TRANSPORTS = 12
BED_SEED = 7000  # apart from GENERATED_SEED (worker.training.cli), the demo's and the fleet's
BED_DURATION_S = 8.0  # the generator makes room for walking, sitting, lying down and lying


def bed_recordings(
    n: int = BED_TRANSPORTS, seed: int = BED_SEED, duration_s: float = BED_DURATION_S
) -> tuple[list[Recording], str]:
    """`n` GENERATED walking transports of a patient lying down on a bed, as the generated
    source gives them (`generated_recordings`: the patient alone, targets for walking mode),
    without depth at the keypoints, as URFD's recordings."""
    digest = hashlib.sha256()
    recordings = []
    classes = MODE_CLASSES[TransportMode.WALKING]
    for k in range(n):
        transport = generate_transport(
            Locomotion.WALKING, seed=seed + k, duration_s=duration_s, events=[BED_EVENT]
        )
        recordings.append(_recording(transport, TransportMode.WALKING, classes, depth=False))
        digest.update(recordings[-1].name.encode())
        digest.update(transport.patient_sequence().keypoints.tobytes())
    return recordings, digest.hexdigest()


def bed_frames(n: int = BED_TRANSPORTS, seed: int = BED_SEED) -> FrameData:
    """Training rows of `bed_recordings` (the one builder, `build_rows`)."""
    recordings, digest = bed_recordings(n, seed)
    return build_rows(recordings, TransportMode.WALKING, digest)
