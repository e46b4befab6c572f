"""Frames of whole sequences as arrays for training: features, targets, timestamps, groups.

`build_rows` is the one builder of training rows; sources hand it `Recording`s (observations as
the robot's camera gives them, and per-frame targets) and it computes features on the robot's own
streaming path (docs/detection.md, "train equals serve")."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.datasets import urfd
from vigil.detector import stream_features
from vigil.observation import Observation
from vigil.policy import TIME_EPSILON


@dataclass(frozen=True)
class FrameData:
    """Frames of several sequences concatenated in order; `group` is the sequence index."""

    names: list[str]
    is_positive_sequence: np.ndarray  # (s,) e.g. fall sequences
    features: np.ndarray  # (n, d) float32
    target: np.ndarray  # (n,) class index, -1 = unlabelled
    group: np.ndarray  # (n,) sequence index
    timestamps: np.ndarray  # (n,)
    usable: np.ndarray  # (n,) bool: a pose was seen (train only on these)
    mode: TransportMode
    data_sha256: str
    generated: bool = False
    # What the models are fitted to, where it differs from `target` (which thresholds, delays and
    # every evaluation use): see with_emergency_lead.
    training_target: np.ndarray | None = None
    # Per sequence, the recording as observations: evaluations replay it through the robot's
    # frame path (vigil.replay). Features above are computed from the same path's frames.
    recordings: tuple[tuple[Observation, ...], ...] | None = None

    @property
    def classes(self):
        return MODE_CLASSES[self.mode]

    @property
    def fit_target(self) -> np.ndarray:
        return self.target if self.training_target is None else self.training_target

    @property
    def trainable(self) -> np.ndarray:
        return (self.target >= 0) & self.usable

    @property
    def scored(self) -> np.ndarray:
        return self.target >= 0

    def frames_of(self, sequence_indices: np.ndarray) -> np.ndarray:
        return np.isin(self.group, sequence_indices)

    def sequence_slices(self) -> list[slice]:
        bounds = np.flatnonzero(np.diff(self.group)) + 1
        starts = np.concatenate([[0], bounds])
        ends = np.concatenate([bounds, [len(self.group)]])
        return [slice(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def with_emergency_lead(data: FrameData, lead_s: float) -> FrameData:
    """A copy whose models are fitted to Emergency starting `lead_s` earlier: the Normal frames
    within `lead_s` before each start of an Emergency run are fitted as Emergency. Thresholds,
    delays and evaluation keep the labelled targets."""
    if not lead_s >= 0:
        raise ValueError(f"emergency lead must be >= 0 s, got {lead_s!r}")
    e, normal = data.classes.index(Decision.EMERGENCY), data.classes.index(Decision.NORMAL)
    fit = data.target.copy()
    for rows in data.sequence_slices():
        target, times = data.target[rows], data.timestamps[rows]
        index = np.arange(len(target))
        starts = np.flatnonzero((target == e) & np.r_[True, target[:-1] != e])
        for k in starts:
            early = (index < k) & (times >= times[k] - lead_s - TIME_EPSILON) & (target == normal)
            fit[rows.start + index[early]] = e
    return replace(data, training_target=fit)


def concatenate(*parts: FrameData) -> FrameData:
    """Several FrameData of one mode as one (sequence indices renumbered, recordings kept). The
    result is `generated` if any part is: every figure from it must say so."""
    if len({part.mode for part in parts}) != 1:
        raise ValueError("FrameData of different modes cannot be concatenated")
    if any(part.training_target is not None for part in parts):
        raise ValueError("concatenate the labelled data first, then apply with_emergency_lead")
    groups, offset = [], 0
    for part in parts:
        groups.append(part.group + offset)
        offset += len(part.names)
    digest = hashlib.sha256("+".join(part.data_sha256 for part in parts).encode()).hexdigest()
    recordings = (
        tuple(r for part in parts for r in part.recordings)  # type: ignore[union-attr]
        if all(part.recordings is not None for part in parts)
        else None
    )
    return FrameData(
        names=[name for part in parts for name in part.names],
        is_positive_sequence=np.concatenate([part.is_positive_sequence for part in parts]),
        features=np.concatenate([part.features for part in parts]),
        target=np.concatenate([part.target for part in parts]),
        group=np.concatenate(groups),
        timestamps=np.concatenate([part.timestamps for part in parts]),
        usable=np.concatenate([part.usable for part in parts]),
        mode=parts[0].mode,
        data_sha256=digest,
        generated=any(part.generated for part in parts),
        recordings=recordings,
    )


@dataclass(frozen=True)
class Recording:
    """One recording as a source gives it to the builder: what the camera saw, frame by frame,
    and the class of each frame in the mode's class order (-1: unlabelled)."""

    name: str
    observations: tuple[Observation, ...]
    target: np.ndarray  # (n,) class index, -1 = unlabelled
    generated: bool = False

    def __post_init__(self) -> None:
        if len(self.target) != len(self.observations):
            raise ValueError(
                f"recording {self.name}: {len(self.target)} targets for "
                f"{len(self.observations)} frames"
            )


def build_rows(
    recordings: list[Recording],
    mode: TransportMode | str,
    data_sha256: str,
    feature_set: str = "full",
) -> FrameData:
    """The one builder of training rows (issue #34), fed by sources: URFD files
    (`urfd_recordings`), database recordings with their accepted segments
    (`worker.db_data.db_recordings`) and generated transports
    (`worker.training.generated.generated_recordings`). Each recording's features come from the
    robot's own streaming path (`vigil.detector.stream_features`: tracker, `vigil.depth`,
    `vigil.floor`, `vigil.features.FeatureExtractor`), so a model is trained on the numbers it is
    served. A sequence is positive (a fall) when any of its frames is Emergency."""
    if not recordings:
        raise ValueError("no recordings to build training rows from")
    mode = TransportMode(mode)
    emergency = MODE_CLASSES[mode].index(Decision.EMERGENCY)
    feats, targets, groups, times, usable, positive = [], [], [], [], [], []
    for i, recording in enumerate(recordings):
        features, seen = stream_features(recording.observations, feature_set)
        target = np.asarray(recording.target, np.int64)
        feats.append(features)
        targets.append(target)
        groups.append(np.full(len(target), i))
        times.append(np.array([o.timestamp for o in recording.observations], np.float64))
        usable.append(seen)
        positive.append(bool(np.any(target == emergency)))
    return FrameData(
        names=[r.name for r in recordings],
        is_positive_sequence=np.array(positive),
        features=np.concatenate(feats),
        target=np.concatenate(targets),
        group=np.concatenate(groups),
        timestamps=np.concatenate(times),
        usable=np.concatenate(usable),
        mode=mode,
        data_sha256=data_sha256,
        generated=any(r.generated for r in recordings),
        recordings=tuple(r.observations for r in recordings),
    )


def urfd_recordings(
    directory=None, names: list[str] | None = None, depth: bool = True
) -> tuple[list[Recording], str]:
    """The URFD file source: each sequence as the robot's replay gives it (its depth pictures
    attached where there are any, unless `depth` is False), targets from the official labels;
    and the hash of the files read."""
    directory = Path(directory) if directory else urfd.default_dir()
    depth_dir = directory / urfd.DEPTH_DIR if depth else None
    sequences = urfd.load(directory, names)  # first: its errors name VIGIL_URFD_DIR
    digest = hashlib.sha256(urfd.data_sha256(directory).encode())
    recordings = []
    for sequence in sequences:
        if depth_dir is not None:
            for path in sequence.depth_pictures(depth_dir).values():
                digest.update(path.read_bytes())
        recordings.append(
            Recording(sequence.name, tuple(sequence.observations(depth_dir)), sequence.target)
        )
    return recordings, digest.hexdigest()


def from_urfd(
    directory=None, names: list[str] | None = None, feature_set: str = "full"
) -> FrameData:
    recordings, digest = urfd_recordings(directory, names)
    return build_rows(recordings, TransportMode.WALKING, digest, feature_set)
