"""A directory of OpenPose JSON files (`--write_json`), optionally with 16-bit depth PNGs.

Frame numbers come from the file names (`<name>_000000000012_keypoints.json` -> 12); a depth
picture belongs to the frame whose number is the last group of digits in its name. Of several
people in a frame, the one with the highest summed keypoint confidence is kept.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
from sqlalchemy.orm import Session

from backend.labelling.depth import read_depth_png
from backend.labelling.errors import LabellingError
from backend.labelling.store import add_video
from backend.models.videos import Split, Video
from vigil.classes import TransportMode
from vigil.depth import sample_depth
from vigil.formats import from_openpose_json
from vigil.skeleton import N_KEYPOINTS, empty_keypoints

FRAME_NUMBER = re.compile(r"(\d+)(?!.*\d)")


def _frame_number(path: Path) -> int:
    match = FRAME_NUMBER.search(path.stem)
    if match is None:
        raise LabellingError(f"openpose: {path.name} has no frame number in its name")
    return int(match.group(1))


def import_openpose_dir(
    session: Session,
    directory: Path,
    name: str,
    *,
    mode: TransportMode = TransportMode.WALKING,
    fps: float = 30.0,
    depth_dir: Path | None = None,
    depth_metres_per_unit: float = 0.001,
    person: str | None = None,
    location: str | None = None,
    camera: str | None = None,
    split: Split = Split.UNASSIGNED,
) -> Video:
    files = sorted(Path(directory).glob("*.json"), key=_frame_number)
    if not files:
        raise LabellingError(f"directory: no OpenPose .json files in {directory}")
    numbers = [_frame_number(path) for path in files]
    if len(set(numbers)) != len(numbers):
        raise LabellingError("directory: two JSON files carry the same frame number")
    first_number = numbers[0]
    keypoints = np.zeros((len(files), N_KEYPOINTS, 3), np.float32)
    for i, path in enumerate(files):
        try:
            people = from_openpose_json(json.loads(path.read_text()))
        except (json.JSONDecodeError, ValueError) as error:
            raise LabellingError(f"openpose: {path.name}: {error}") from error
        best = max(people, key=lambda p: float(p.keypoints[:, 2].sum()), default=None)
        keypoints[i] = best.keypoints if best is not None else empty_keypoints()
    indices = [n - first_number for n in numbers]
    depth = None
    size = (None, None)
    if depth_dir is not None:
        depth = np.full((len(files), N_KEYPOINTS), np.nan, np.float32)
        position = {n: i for i, n in enumerate(numbers)}
        for png in sorted(Path(depth_dir).glob("*.png")):
            i = position.get(_frame_number(png))
            if i is not None:
                picture = read_depth_png(png)
                size = (float(picture.shape[1]), float(picture.shape[0]))
                depth[i] = sample_depth(picture, keypoints[i], depth_metres_per_unit * 1000)
    video = Video(
        name=name,
        source="openpose",
        mode=mode,
        fps=fps,
        person=person,
        location=location,
        camera=camera,
        split=split,
        image_width=size[0],
        image_height=size[1],
        depth_path=str(depth_dir) if depth_dir else None,
    )
    return add_video(session, video, keypoints, [i / fps for i in indices], depth, indices)
