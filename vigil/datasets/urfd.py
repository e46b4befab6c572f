"""UR Fall Detection dataset (real falls, Kwolek & Kepski 2014, CC BY-NC-SA 4.0).

Label mapping (the dataset README): Emergency = frames of fall-* sequences labelled 0 or 1;
Normal = fall-* frames labelled -1 and every labelled frame of adl-* sequences (ADL lying is a
deliberate lie-down, a hard negative). Unlabelled frames get target -1 and are excluded from
training and scoring, but stay in the stream so time passes for the delay filter.

Frames with detected = 0 (the pose estimator found nobody) have all keypoints missing. They stay
in the stream: the feature extractor repeats the last seen pose for them (see vigil.features),
so the decision holds; they are left out of training and count in scoring with that held decision.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vigil.formats.coco import MOVENET13, movenet13_to_body25
from vigil.skeleton import SkeletonFrame

FPS = 30.0
IMAGE_SIZE = (640.0, 480.0)
KEYPOINTS_FILE = "keypoints/urfd_movenet13.csv.gz"
UNLABELLED = -1
NORMAL, EMERGENCY = 0, 1  # indices into MODE_CLASSES[WALKING]


def default_dir() -> Path:
    env = os.environ.get("VIGIL_URFD_DIR")
    if env:
        return Path(env)
    # ../shared/datasets/urfd relative to the repo root; a git worktree sits deeper, so the
    # nearest ancestor holding shared/datasets/urfd wins.
    repo_root = Path(__file__).resolve().parents[2]
    for ancestor in repo_root.parents:
        candidate = ancestor / "shared" / "datasets" / "urfd"
        if candidate.is_dir():
            return candidate
    return (repo_root.parent / "shared" / "datasets" / "urfd").resolve()


@dataclass(frozen=True, slots=True)
class Sequence:
    name: str
    keypoints: np.ndarray  # (n, 25, 3) pixels of the 640x480 image
    timestamps: np.ndarray  # (n,) seconds from the first frame
    urfd_label: np.ndarray  # (n,) -1, 0, 1, or NaN where the official files have no label
    target: np.ndarray  # (n,) NORMAL, EMERGENCY or UNLABELLED
    detected: np.ndarray  # (n,) bool

    @property
    def is_fall(self) -> bool:
        return self.name.startswith("fall-")

    def __len__(self) -> int:
        return len(self.timestamps)

    def frames(self) -> list[SkeletonFrame]:
        return [
            SkeletonFrame(keypoints=k, timestamp=float(t))
            for k, t in zip(self.keypoints, self.timestamps, strict=True)
        ]

    def first_emergency_time(self) -> float | None:
        hits = np.flatnonzero(self.target == EMERGENCY)
        return float(self.timestamps[hits[0]]) if hits.size else None


def target_for(sequence: str, urfd_label: np.ndarray) -> np.ndarray:
    target = np.full(urfd_label.shape, UNLABELLED, np.int64)
    labelled = ~np.isnan(urfd_label)
    if sequence.startswith("fall-"):
        target[labelled] = np.where(urfd_label[labelled] >= 0, EMERGENCY, NORMAL)
    else:
        target[labelled] = NORMAL
    return target


def data_sha256(directory: Path | str | None = None) -> str:
    path = Path(directory or default_dir()) / KEYPOINTS_FILE
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load(directory: Path | str | None = None, names: list[str] | None = None) -> list[Sequence]:
    """All sequences (or those named), in the order fall-01..fall-30, adl-01..adl-40."""
    path = Path(directory or default_dir()) / KEYPOINTS_FILE
    if not path.exists():
        raise FileNotFoundError(f"URFD keypoints not found at {path} (set VIGIL_URFD_DIR)")
    rows: dict[str, list[list[str]]] = {}
    with gzip.open(path, "rt", newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        column = {name: i for i, name in enumerate(header)}
        xy_columns = [column[f"{kp}_{axis}"] for kp in MOVENET13 for axis in ("x", "y")]
        for row in reader:
            rows.setdefault(row[column["sequence"]], []).append(row)
    wanted = names if names is not None else sorted(rows, key=_sequence_order)
    sequences = []
    for name in wanted:
        if name not in rows:
            raise KeyError(f"URFD has no sequence {name!r}")
        seq_rows = sorted(rows[name], key=lambda r: int(r[column["npy_index"]]))
        index = np.array([int(r[column["npy_index"]]) for r in seq_rows])
        label = np.array(
            [
                float(r[column["urfd_label"]]) if r[column["urfd_label"]] else np.nan
                for r in seq_rows
            ]
        )
        detected = np.array([r[column["detected"]] == "1" for r in seq_rows])
        xy = np.array([[float(r[i]) for i in xy_columns] for r in seq_rows], np.float32)
        keypoints = movenet13_to_body25(xy.reshape(-1, 13, 2), IMAGE_SIZE)
        keypoints[~detected] = 0.0
        sequences.append(
            Sequence(
                name=name,
                keypoints=keypoints,
                timestamps=(index - index[0]) / FPS,
                urfd_label=label,
                target=target_for(name, label),
                detected=detected,
            )
        )
    return sequences


def _sequence_order(name: str) -> tuple[int, int]:
    kind, number = name.split("-")
    return (0 if kind == "fall" else 1, int(number))
