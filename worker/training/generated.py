"""FrameData from GENERATED transports (vigil.synthetic) for the wheelchair and combined modes,
which URFD cannot provide, and the walking situations URFD lacks (turning, lying on a bed,
stumbling, a rollator: `make run`'s demo model, `worker.training.cli train-default
--with-generated`). Every figure and model made from it is labelled generated."""

from __future__ import annotations

import hashlib

import numpy as np

from vigil.classes import MODE_CLASSES, TransportMode
from vigil.formats.coco import MOVENET13, movenet13_to_body25
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
    digest = hashlib.sha256()
    recordings = []
    for transport in generate_for_mode(mode, repeats, seed):
        keypoints, depths, usable, floor = patient_arrays(transport)
        if not depth:
            depths = np.full_like(depths, np.nan)
        name = f"gen-{transport.locomotion.value}-{'+'.join(transport.events)}-{transport.seed:03d}"
        recordings.append(_recording(name, transport, mode, keypoints, depths, usable, floor))
        digest.update(keypoints.tobytes())
    return recordings, digest.hexdigest()


def _recording(
    name: str,
    transport: GeneratedTransport,
    mode: TransportMode,
    keypoints: np.ndarray,
    depths: np.ndarray,
    usable: np.ndarray,
    floor: np.ndarray,
) -> Recording:
    """One generated transport as the robot would observe it (the patient where usable),
    targets from the generator's decisions for `mode`."""
    timestamps = np.arange(transport.n_frames) / transport.fps
    observations = tuple(
        Observation(
            float(ts),
            [SkeletonFrame(keypoints[t], depths[t], float(ts), floor[t])] if usable[t] else [],
            t,
        )
        for t, ts in enumerate(timestamps)
    )
    classes = MODE_CLASSES[mode]
    target = np.array([classes.index(d) for d in transport.decisions(mode)])
    return Recording(name, observations, target, generated=True)


#: Daily activities that end where a fall ends, as far as 2D keypoints tell (issue #34).
LOOK_ALIKE_EVENTS = ("lying_down_deliberately",)


def hard_negatives(
    events: tuple[str, ...] = LOOK_ALIKE_EVENTS, repeats: int = 10, seed: int = 1000
) -> FrameData:
    """GENERATED walking transports of look-alike daily activities (Normal throughout), shown
    as URFD shows its people: MoveNet's 13 keypoints only, each present one with confidence 1,
    no depth at the keypoints. Otherwise a keypoints-only model could tell generated from real
    by the 12 extra keypoints and the generator's confidences instead of by the pose.
    For training only, never scored (`cross_validate(train_only=...)`)."""
    urfd_slots = movenet13_to_body25(np.ones((1, len(MOVENET13), 3), np.float32))[0, :, 2] > 0
    recordings, digest = [], hashlib.sha256()
    for index, event in enumerate(events):
        for repeat in range(repeats):
            transport = generate_transport(
                Locomotion.WALKING,
                seed=seed + index * repeats + repeat,
                duration_s=10.0,
                events=[event],
            )
            keypoints, depths, usable, floor = patient_arrays(transport)
            keypoints = keypoints.copy()
            present = (keypoints[:, :, 2] > 0) & urfd_slots
            keypoints[:, :, 2] = present.astype(np.float32)
            keypoints[~present, :2] = 0.0
            depths = np.full_like(depths, np.nan)
            name = f"gen-hard-{event}-{transport.seed:04d}"
            recordings.append(
                _recording(name, transport, TransportMode.WALKING, keypoints, depths, usable, floor)
            )
            digest.update(keypoints.tobytes())
    return build_rows(recordings, TransportMode.WALKING, digest.hexdigest())


def generated_frames(
    mode: TransportMode | str, repeats: int | None = None, seed: int = 0, depth: bool = True
) -> FrameData:
    """Training rows of generated transports (the one builder, `build_rows`, fed by the
    generated source); see `generated_recordings`."""
    recordings, digest = generated_recordings(mode, repeats, seed, depth)
    return build_rows(recordings, mode, digest)
