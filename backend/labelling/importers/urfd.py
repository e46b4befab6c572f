"""UR Fall Detection (real falls; Kwolek & Kepski 2014, CC BY-NC-SA 4.0) -> videos + labels.

The one URFD importer: the demo seeding, the worker's bootstrap and CLI, tests and benchmarks
all import through it, one video per sequence named after it (`fall-01`). Official per-frame
labels map onto the taxonomy as imported, accepted segments by the one map,
`vigil.datasets.urfd.FINE_LABELS`:

| sequence | -1 (not lying) | 0 (in between)  | 1 (lying on the ground)   |
| -------- | -------------- | --------------- | ------------------------- |
| fall-*   | walking        | falling         | lying_on_floor            |
| adl-*    | walking        | bending         | lying_down_deliberately   |

ADL "0" is a transitional pose (crouching, bending down, sitting down); the data cannot tell
these apart, so one label is used for all of them: `bending`, Normal in every mode as is
`sitting_down`. Frames without an official label get no segment.

Frame index i is the i-th row of the keypoint extraction (npy_index - 1). Those keypoints
belong to official picture max(i, 1); the clip's 0-based frame is therefore i - 1
(Video.rgb_frame_offset = -1) and depth picture fall-01-cam0-d-NNN.png belongs to the row whose
official picture is NNN (`urfd.Sequence.depth_pictures`, as the robot's replay pairs them). The
depth stored at the keypoints is sampled by the robot's sampler, `vigil.depth.sample_depth`,
with the sequence's scale (`urfd.DEPTH_SCALE_MM`): what the robot computes from that picture.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.labelling.depth import read_depth_png
from backend.labelling.segments import SegmentDraft, create_segment
from backend.labelling.store import add_video, video_by_name
from backend.models.annotations import SegmentSource
from backend.models.videos import Split, Video
from vigil.classes import TransportMode
from vigil.datasets import urfd
from vigil.depth import sample_depth
from vigil.segments import label_runs

#: The URFD clip: 640x240, depth picture left, RGB (320x240) right.
RGB_CROP = {"x": 320, "y": 0, "width": 320, "height": 240}
#: Nominal Kinect v1 colour-camera intrinsics at 640x480 (URFD publishes no calibration).
KINECT_INTRINSICS = {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}


@dataclass
class ImportReport:
    created: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    segments: int = 0
    #: Every video of the sequences asked for, imported now or before, in the order loaded.
    videos: list[Video] = field(default_factory=list)


def split_for(name: str) -> Split:
    """Every 5th sequence of each kind is a test (gold) video: split by video, never frame."""
    return Split.TEST if urfd.is_gold(name) else Split.TRAIN


def _depth_for(directory: Path, sequence: urfd.Sequence) -> np.ndarray | None:
    """(n, 25) depth at the keypoints of the rows with a depth picture (NaN elsewhere), sampled
    as the robot samples it; None when the sequence has no depth picture."""
    pictures = sequence.depth_pictures(directory / urfd.DEPTH_DIR)
    if not pictures:
        return None
    depth = np.full((len(sequence), 25), np.nan, np.float32)
    for row, path in pictures.items():
        depth[row] = sample_depth(
            read_depth_png(path), sequence.keypoints[row], sequence.depth_scale_mm
        )
    return depth


def _skip(video: Video, report: ImportReport, split: Split | None) -> None:
    if split is not None:
        video.split = split
    report.skipped.append(video.name)
    report.videos.append(video)


def _to_load(
    session: Session,
    directory: Path,
    names: list[str] | None,
    report: ImportReport,
    split: Split | None,
) -> list[urfd.Sequence]:
    """The sequences still to import, read from the keypoint file only when there are any (a
    second `make run` reads nothing); the videos already there go to the report."""
    wanted = list(names) if names is not None else list(urfd.NAMES)
    there = {
        video.name: video
        for video in session.scalars(
            select(Video).where(Video.name.in_(wanted), Video.source == "urfd")
        )
    }
    if names is None and len(there) < len(wanted):
        return urfd.load(directory)  # every sequence of the file, as asked
    for name in wanted:
        if name in there:
            _skip(there[name], report, split)
    missing = [name for name in wanted if name not in there]
    return urfd.load(directory, missing) if missing else []


def import_urfd(
    session: Session,
    directory: Path | str | None = None,
    names: list[str] | None = None,
    labels: bool = True,
    sequences: list[urfd.Sequence] | None = None,
    split: Split | None = None,
) -> ImportReport:
    """Idempotent: sequences already imported (by video name) are skipped. labels=False
    imports the recordings only (to label them from scratch). `sequences` saves re-reading
    the keypoint file when the caller has already loaded them. `split` puts every video asked
    for in that split, those imported before included (default: `split_for` on new videos)."""
    directory = Path(directory) if directory else urfd.default_dir()
    report = ImportReport()
    if sequences is None:
        sequences = _to_load(session, directory, names, report, split)
    for sequence in sequences:
        existing = video_by_name(session, sequence.name)
        if existing is not None:
            _skip(existing, report, split)
            continue
        clip = directory / "video" / f"{sequence.name}-cam0.mp4"
        video = Video(
            name=sequence.name,
            source="urfd",
            generated=False,
            mode=TransportMode.WALKING,
            camera="urfd-kinect-cam0",
            location="URFD lab (Rzeszow)",
            person=None,  # URFD does not say who is in which sequence
            split=split if split is not None else split_for(sequence.name),
            fps=urfd.FPS,
            image_width=urfd.IMAGE_SIZE[0],
            image_height=urfd.IMAGE_SIZE[1],
            rgb_path=str(clip) if clip.is_file() else None,
            rgb_crop=RGB_CROP if clip.is_file() else None,
            rgb_frame_offset=-1,
            intrinsics=KINECT_INTRINSICS,
        )
        depth = _depth_for(directory, sequence)
        if depth is not None:
            video.depth_path = str(directory / "depth")
        indices = np.rint(sequence.timestamps * urfd.FPS).astype(int)
        add_video(
            session,
            video,
            sequence.keypoints,
            sequence.timestamps,
            depth=depth,
            indices=indices,
            floor=sequence.floor,
        )
        official = [
            urfd.fine_label(sequence.name, value) if labels else None
            for value in sequence.urfd_label
        ]
        for first, last, label in label_runs(official):
            create_segment(
                session,
                video,
                SegmentDraft(int(indices[first]), int(indices[last]), label),
                None,
                source=SegmentSource.IMPORT,
                entry="import",
            )
            report.segments += 1
        report.created.append(sequence.name)
        report.videos.append(video)
    session.flush()
    return report
