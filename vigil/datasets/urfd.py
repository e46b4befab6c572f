"""UR Fall Detection dataset (real falls, Kwolek & Kepski 2014, CC BY-NC-SA 4.0).

Label mapping (the dataset README): Emergency = frames of fall-* sequences labelled 0 or 1;
Normal = fall-* frames labelled -1 and every labelled frame of adl-* sequences (ADL lying is a
deliberate lie-down, a hard negative). Unlabelled frames get target -1 and are excluded from
training and scoring, but stay in the stream so time passes for the delay filter.

Frames with detected = 0 (the pose estimator found nobody) have all keypoints missing. They stay
in the stream: the feature extractor repeats the last seen pose for them (see vigil.features),
so the decision holds; they are left out of training and count in scoring with that held decision.

Floor measures come from the official per-frame depth features (labels/urfall-cam0-*.csv, joined
on the official frame index): H (top above the floor) and D (centroid above the floor) in mm
become metres, P40 (share of the silhouette within 40 cm of the floor) stays a share. They are
NaN where the official files have no row for a frame (the same 409 ADL frames without a label).

Depth pictures (``depth/<sequence>-cam0-d-NNN.png``, 16-bit, raw * DEPTH_SCALE_MM[kind] is mm)
belong to the keypoint row whose official frame (``image_frame``) is NNN; where two rows share an
official frame (the first two), the later row gets it. ``Sequence.observations(depth_dir)``
attaches them as a camera would: the robot's replay, the training rows and the importer all
take them from there, and sample them with the one sampler, ``vigil.depth.sample_depth``.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vigil.depth import read_depth_png
from vigil.formats.coco import MOVENET13, movenet13_to_body25
from vigil.observation import Observation
from vigil.skeleton import SkeletonFrame

FPS = 30.0
IMAGE_SIZE = (640.0, 480.0)
KEYPOINTS_FILE = "keypoints/urfd_movenet13.csv.gz"
LABEL_FILES = ("labels/urfall-cam0-falls.csv", "labels/urfall-cam0-adls.csv")
UNLABELLED = -1
NORMAL, EMERGENCY = 0, 1  # indices into MODE_CLASSES[WALKING]
#: The one map from URFD's official per-frame label to a fine label of the taxonomy
#: (vigil.taxonomy), by sequence kind; docs/labelling.md states it. The URFD importer
#: (backend.labelling.importers.urfd) stores it as accepted import segments, and a replayed
#: observation carries it as its truth. ADL "0" is a transitional pose (crouching, bending
#: down, sitting down) the data cannot tell apart: one label, `bending`, stands for all of them.
FINE_LABELS: dict[str, dict[int, str]] = {
    "fall": {-1: "walking", 0: "falling", 1: "lying_on_floor"},
    "adl": {-1: "walking", 0: "bending", 1: "lying_down_deliberately"},
}
TRUTH_LABELS = {
    (kind, float(value)): label
    for kind, labels in FINE_LABELS.items()
    for value, label in labels.items()
}
#: Every fifth sequence of each kind is a gold (test) recording: 6 falls and 8 daily activities,
#: 56 training recordings (split by recording, never by frame).
TEST_EVERY = 5
#: Raw depth value -> millimetres, by sequence kind (dataset README: 6000 mm full range for falls,
#: 7000 for daily activities, over 65535).
DEPTH_SCALE_MM = {"fall": 6000 / 65535, "adl": 7000 / 65535}
DEPTH_DIR = "depth"
NAMES = tuple([f"fall-{i:02d}" for i in range(1, 31)] + [f"adl-{i:02d}" for i in range(1, 41)])


def fine_label(name: str, urfd_label: float) -> str | None:
    """The fine label of one official label of sequence `name` (None where unlabelled)."""
    if np.isnan(urfd_label):
        return None
    return FINE_LABELS[name.split("-")[0]][int(urfd_label)]


def depth_scale_mm(name: str) -> float:
    """Raw depth value -> millimetres for URFD sequence `name`."""
    return DEPTH_SCALE_MM[name.split("-")[0]]


def is_gold(name: str) -> bool:
    """Whether URFD sequence `name` (e.g. "fall-05") belongs to the gold set."""
    return int(name.split("-")[1]) % TEST_EVERY == 0


def split() -> tuple[list[str], list[str]]:
    """URFD's training recordings and its gold set (`is_gold`: 56 and 14), in NAMES order: the
    demo's models are trained on the first and judged on the second."""
    return [n for n in NAMES if not is_gold(n)], [n for n in NAMES if is_gold(n)]


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
    floor: np.ndarray  # (n, 3) floor measures from the official depth features, NaN if unknown
    #: (n,) official frame (picture number) of each row; None: the documented max(row, 1)
    image_frame: np.ndarray | None = None

    @property
    def is_fall(self) -> bool:
        return self.name.startswith("fall-")

    def __len__(self) -> int:
        return len(self.timestamps)

    def frames(self) -> list[SkeletonFrame]:
        return [
            SkeletonFrame(keypoints=k, timestamp=float(t), floor=f)
            for k, t, f in zip(self.keypoints, self.timestamps, self.floor, strict=True)
        ]

    def truth(self) -> list[str | None]:
        """Per frame, the fine label of FINE_LABELS (None where unlabelled)."""
        return [fine_label(self.name, v) for v in self.urfd_label]

    @property
    def depth_scale_mm(self) -> float:
        return depth_scale_mm(self.name)

    def depth_pictures(self, depth_dir: Path | str) -> dict[int, Path]:
        """Row -> its depth picture in `depth_dir` (rows without one are left out); the later
        row wins where two share an official frame."""
        depth_dir = Path(depth_dir)
        if not depth_dir.is_dir():
            return {}
        frames = (
            self.image_frame
            if self.image_frame is not None
            else np.maximum(np.arange(len(self)), 1)
        )
        row_of = {int(frame): row for row, frame in enumerate(frames)}
        pictures = {}
        for path in sorted(depth_dir.glob(f"{self.name}-cam0-d-*.png")):
            number = path.stem.rsplit("-", 1)[-1]
            row = row_of.get(int(number)) if number.isdigit() else None
            if row is not None:
                pictures[row] = path
        return dict(sorted(pictures.items()))

    def observations(self, depth_dir: Path | str | None = None) -> list[Observation]:
        """The sequence as a camera would have given it: one person where MoveNet found
        somebody (with the official floor measures), nobody where it did not; with
        `depth_dir`, the rows that have a depth picture carry it (and its scale)."""
        pictures = self.depth_pictures(depth_dir) if depth_dir is not None else {}
        out = []
        for i, (truth, ts) in enumerate(zip(self.truth(), self.timestamps, strict=True)):
            ts = float(ts)
            people = (
                [SkeletonFrame(self.keypoints[i], timestamp=ts, floor=self.floor[i])]
                if self.detected[i]
                else []
            )
            observation = Observation(timestamp=ts, people=people, index=i, truth=truth)
            if i in pictures:
                observation.depth_image = read_depth_png(pictures[i])
            observation.depth_scale_mm = self.depth_scale_mm
            out.append(observation)
        return out

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
    digest = hashlib.sha256()
    for name in (KEYPOINTS_FILE, *LABEL_FILES):
        digest.update((Path(directory or default_dir()) / name).read_bytes())
    return digest.hexdigest()


def _floor_features(
    directory: Path, required: bool = True
) -> dict[tuple[str, int], tuple[float, float, float]]:
    """(sequence, official frame) -> (H m, D m, P40) from the official label files (none when
    they are not there and not ``required``)."""
    floor = {}
    for name in LABEL_FILES:
        path = directory / name
        if not path.exists():
            if not required:
                return {}
            raise FileNotFoundError(f"URFD labels not found at {path} (set VIGIL_URFD_DIR)")
        with path.open(newline="") as handle:
            for row in csv.reader(handle):
                sequence, frame = row[0], int(row[1])
                height, centre, near = float(row[8]), float(row[9]), float(row[10])
                floor[(sequence, frame)] = (height / 1000.0, centre / 1000.0, near)
    return floor


def load(
    directory: Path | str | None = None,
    names: list[str] | None = None,
    keypoints_file: Path | str | None = None,
) -> list[Sequence]:
    """All sequences (or those named), in the order fall-01..fall-30, adl-01..adl-40.

    keypoints_file: a keypoint file in URFD's format anywhere (default: the dataset's own);
    its floor measures come from the label files of the dataset layout around it
    (``<file>/../../labels``) when they are there, else they are unknown."""
    if keypoints_file is not None:
        path = Path(keypoints_file)
        directory = path.parent.parent
    else:
        directory = Path(directory or default_dir())
        path = directory / KEYPOINTS_FILE
    if not path.exists():
        raise FileNotFoundError(f"URFD keypoints not found at {path} (set VIGIL_URFD_DIR)")
    rows: dict[str, list[list[str]]] = {}
    with gzip.open(path, "rt", newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        column = {name: i for i, name in enumerate(header)}
        wanted_columns = ("sequence", "npy_index", "image_frame", "urfd_label", "detected")
        absent = [name for name in wanted_columns if name not in column]
        absent += [f"{kp}_{a}" for kp in MOVENET13 for a in "xy" if f"{kp}_{a}" not in column]
        if absent:
            raise ValueError(f"{path}: not in URFD's keypoint format, missing columns {absent[:5]}")
        xy_columns = [column[f"{kp}_{axis}"] for kp in MOVENET13 for axis in ("x", "y")]
        for row in reader:
            rows.setdefault(row[column["sequence"]], []).append(row)
    floor_of = _floor_features(directory, required=keypoints_file is None)
    missing_floor = (np.nan, np.nan, np.nan)
    wanted = names if names is not None else sorted(rows, key=_sequence_order)
    sequences = []
    for name in wanted:
        if name not in rows:
            raise KeyError(f"URFD has no sequence {name!r}")
        seq_rows = sorted(rows[name], key=lambda r: int(r[column["npy_index"]]))
        index = np.array([int(r[column["npy_index"]]) for r in seq_rows])
        repeated = index[1:][np.diff(index) == 0]
        if repeated.size:
            raise ValueError(
                f"{path}: sequence {name} has more than one row for npy_index "
                f"{', '.join(str(int(i)) for i in np.unique(repeated)[:5])}: every frame must "
                "appear once (two rows for one frame would make a zero-length time step)"
            )
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
        floor = np.array(
            [floor_of.get((name, int(r[column["image_frame"]])), missing_floor) for r in seq_rows],
            np.float32,
        )
        sequences.append(
            Sequence(
                name=name,
                keypoints=keypoints,
                timestamps=(index - index[0]) / FPS,
                urfd_label=label,
                target=target_for(name, label),
                detected=detected,
                floor=floor,
                image_frame=np.array([int(r[column["image_frame"]]) for r in seq_rows], np.int64),
            )
        )
    return sequences


def _sequence_order(name: str) -> tuple[int, int]:
    kind, number = name.split("-")
    return (0 if kind == "fall" else 1, int(number))
