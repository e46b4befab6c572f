"""Replay recorded keypoints: a URFD sequence, or a Vigil JSON label export.

Both pace themselves with ``speed`` (1 real time, 2 twice as fast, 0 as fast as possible).

URFD (real data, ``vigil.datasets.urfd``): ``Sequence.observations()``, one person per frame
where MoveNet found somebody, nobody where it did not, each frame's truth a fine label standing
for the official one (``urfd.FINE_LABELS``, the one URFD map). The sequence comes from the
dataset's keypoint file or from any file in its format (``keypoints_file``). With ``depth_dir``
(URFD depth PNGs ``<sequence>-cam0-d-NNN.png``) the frame whose official index matches carries
its depth image.

Vigil export (``backend/labelling/export.py``, format ``vigil-labels`` version 1): a JSON object
with ``video`` (``fps``, ``image_width``, ``image_height``, ``generated``, ...), ``frames``
(``index``, ``ts`` seconds, ``keypoints`` 25 x [x, y, confidence] in pixels, ``depth`` 25 metres
or null) and ``segments`` (``first_frame``, ``last_frame``, ``label_key``); a frame's truth is
the label of the last segment listed that covers it.
"""

from __future__ import annotations

import csv
import gzip
import json
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from robot_agent.sources.pacing import Pacer
from vigil import depth as vigil_depth
from vigil.datasets import urfd
from vigil.observation import Observation
from vigil.skeleton import N_FLOOR, N_KEYPOINTS, SkeletonFrame

URFD_DEPTH_SCALE_MM = urfd.DEPTH_SCALE_MM["fall"]  # fall sequences (ADL: 7000 / 65535)
URFD_ADL_DEPTH_SCALE_MM = urfd.DEPTH_SCALE_MM["adl"]
EXPORT_FORMAT = "vigil-labels"
EXPORT_VERSIONS = (1,)


class SourceError(ValueError):
    """A recording that cannot be replayed; the message names the file and the field."""


def urfd_image_frames(
    sequence: str, directory: Path | str | None = None, keypoints_file: Path | str | None = None
) -> np.ndarray:
    """Official frame index (``image_frame`` column) of every keypoint row of ``sequence``,
    in the row order of ``vigil.datasets.urfd.load`` (by ``npy_index``)."""
    path = (
        Path(keypoints_file)
        if keypoints_file is not None
        else Path(directory or urfd.default_dir()) / urfd.KEYPOINTS_FILE
    )
    with gzip.open(path, "rt", newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        col = {name: i for i, name in enumerate(header)}
        rows = [
            (int(r[col["npy_index"]]), int(r[col["image_frame"]]))
            for r in reader
            if r[col["sequence"]] == sequence
        ]
    return np.array([frame for _, frame in sorted(rows)], np.int64)


def frame_number(path: Path) -> int | None:
    """The last run of digits in a file's name (``fall-01-cam0-d-002.png`` -> 2)."""
    runs = re.findall(r"\d+", path.stem)
    return int(runs[-1]) if runs else None


def depth_files(directory: Path | str) -> dict[int, Path]:
    """16-bit depth PNGs of a directory by frame number."""
    directory = Path(directory)
    if not directory.is_dir():
        raise SourceError(f"depth directory {directory} does not exist")
    found: dict[int, Path] = {}
    for path in sorted(directory.glob("*.png")):
        number = frame_number(path)
        if number is not None:
            found[number] = path
    return found


def read_depth_png(path: Path) -> np.ndarray:
    """vigil.depth.read_depth_png (the one reader), its error as a SourceError."""
    try:
        return vigil_depth.read_depth_png(path)
    except ValueError as error:
        raise SourceError(f"{path}: {error}") from error


class UrfdReplaySource:
    """A URFD sequence (REAL data) from the shared keypoint file."""

    fps = urfd.FPS
    generated = False

    def __init__(
        self,
        sequence: str = "fall-01",
        directory: Path | str | None = None,
        speed: float = 1.0,
        depth_dir: Path | str | None = None,
        keypoints_file: Path | str | None = None,
    ) -> None:
        self.directory = Path(directory or urfd.default_dir())
        where = keypoints_file or self.directory
        try:
            (self.sequence,) = urfd.load(self.directory, [sequence], keypoints_file)
        except KeyError as error:
            raise SourceError(f"urfd: no sequence {sequence!r} in {where}") from error
        except (FileNotFoundError, ValueError) as error:
            raise SourceError(str(error)) from error
        self.name = f"urfd:{sequence}"
        self.speed = speed
        self.depth = depth_files(depth_dir) if depth_dir is not None else {}
        self.depth_dir = Path(depth_dir) if depth_dir is not None else None
        # row -> depth PNG (vigil.datasets.urfd: where two rows share an official frame, the
        # later one has it); the same pictures the importer and the training rows use
        self.depth_rows: dict[int, Path] = (
            self.sequence.depth_pictures(self.depth_dir) if self.depth_dir is not None else {}
        )
        self.depth_scale_mm = self.sequence.depth_scale_mm

    def __len__(self) -> int:
        return len(self.sequence)

    def __iter__(self) -> Iterator[Observation]:
        pacer = Pacer(self.speed)
        try:
            observations = self.sequence.observations(self.depth_dir)
        except ValueError as error:
            raise SourceError(str(error)) from error
        for observation in observations:
            pacer.wait(observation.timestamp)
            observation.patient_hint = 0 if observation.people else None
            yield observation


def _numbers_or_nulls(frame: dict, key: str, length: int, where: str) -> np.ndarray:
    """An optional list of `length` numbers or nulls (NaN); all NaN when absent or null."""
    values = frame.get(key)
    if values is None:
        return np.full(length, np.nan, np.float32)
    try:
        array = np.array([np.nan if v is None else v for v in values], np.float32)
    except (TypeError, ValueError) as error:
        raise SourceError(f"{where}.{key}: not numbers") from error
    if array.shape != (length,):
        raise SourceError(f"{where}.{key}: must hold {length} numbers or nulls")
    return array


def _field(document: dict, key: str, where: str, kind: type | tuple[type, ...]):
    if key not in document:
        raise SourceError(f"{where}: missing field {key!r}")
    value = document[key]
    if not isinstance(value, kind) or isinstance(value, bool) and bool not in np.atleast_1d(kind):
        raise SourceError(f"{where}.{key}: wrong type {type(value).__name__}")
    return value


class VigilExportSource:
    """A Vigil JSON label export (``vigil-labels`` v1) replayed frame by frame."""

    def __init__(self, path: Path | str, speed: float = 1.0) -> None:
        self.path = Path(path)
        try:
            document = json.loads(self.path.read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise SourceError(f"{self.path}: cannot read JSON ({error})") from error
        where = str(self.path)
        if not isinstance(document, dict) or document.get("format") != EXPORT_FORMAT:
            raise SourceError(f"{where}: format must be {EXPORT_FORMAT!r}")
        if document.get("version") not in EXPORT_VERSIONS:
            raise SourceError(f"{where}.version: unsupported {document.get('version')!r}")
        video = _field(document, "video", where, dict)
        fps = video.get("fps") or 30.0
        if not isinstance(fps, int | float) or fps <= 0:
            raise SourceError(f"{where}.video.fps: must be a positive number")
        self.fps = float(fps)
        self.generated = bool(video.get("generated", False))
        self.name = f"export:{video.get('name', self.path.stem)}"
        frames = _field(document, "frames", where, list)
        self.frames = [self._frame(f, f"{where}.frames[{i}]") for i, f in enumerate(frames)]
        labels: dict[int, str] = {}
        for i, seg in enumerate(_field(document, "segments", where, list)):
            at = f"{where}.segments[{i}]"
            first = _field(seg, "first_frame", at, int)
            last = _field(seg, "last_frame", at, int)
            key = _field(seg, "label_key", at, str)
            if last < first:
                raise SourceError(f"{at}.last_frame: before first_frame")
            for index in range(first, last + 1):
                labels[index] = key
        self.labels = labels
        self.speed = speed

    def _frame(
        self, frame: dict, where: str
    ) -> tuple[int, float, np.ndarray, np.ndarray, np.ndarray]:
        if not isinstance(frame, dict):
            raise SourceError(f"{where}: must be an object")
        index = _field(frame, "index", where, int)
        ts = frame.get("ts")
        ts = index / self.fps if ts is None else ts
        if not isinstance(ts, int | float):
            raise SourceError(f"{where}.ts: must be a number")
        try:
            keypoints = np.asarray(_field(frame, "keypoints", where, list), np.float32)
        except (TypeError, ValueError) as error:
            raise SourceError(f"{where}.keypoints: not numbers") from error
        if keypoints.shape != (N_KEYPOINTS, 3) or not np.isfinite(keypoints).all():
            raise SourceError(f"{where}.keypoints: must be 25 finite [x, y, confidence]")
        depth = _numbers_or_nulls(frame, "depth", N_KEYPOINTS, where)
        floor = _numbers_or_nulls(frame, "floor", N_FLOOR, where)
        return index, float(ts), keypoints, depth, floor

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[Observation]:
        pacer = Pacer(self.speed)
        for index, ts, keypoints, depth, floor in self.frames:
            pacer.wait(ts)
            seen = bool((keypoints[:, 2] > 0).any())
            people = [SkeletonFrame(keypoints, depth, ts, floor)] if seen else []
            yield Observation(
                timestamp=ts,
                people=people,
                index=index,
                truth=self.labels.get(index),
                patient_hint=0 if people else None,
            )
