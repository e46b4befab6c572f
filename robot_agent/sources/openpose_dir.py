"""An OpenPose JSON directory (one file per frame, as ``openpose --write_json`` writes), with
an optional directory of 16-bit depth PNGs matched by frame order."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

from robot_agent.sources import Observation
from vigil.formats import from_openpose_json


def openpose_dir(
    json_dir: Path | str, depth_dir: Path | str | None = None, fps: float = 30.0
) -> Iterator[Observation]:
    import cv2

    files = sorted(Path(json_dir).glob("*.json"))
    if not files:
        raise ValueError(f"source: no OpenPose .json files in {json_dir}")
    depth_files = sorted(Path(depth_dir).glob("*.png")) if depth_dir else []
    if depth_dir and not depth_files:
        raise ValueError(f"depth_dir: no .png files in {depth_dir}")
    for i, path in enumerate(files):
        ts = i / fps
        people = from_openpose_json(json.loads(path.read_text()), timestamp=ts)
        depth = None
        if i < len(depth_files):
            depth = cv2.imread(str(depth_files[i]), cv2.IMREAD_UNCHANGED)
            if depth is None or depth.dtype.name != "uint16":
                raise ValueError(f"depth_dir: {depth_files[i]} is not a 16-bit PNG")
        yield Observation(ts, people, depth_image=depth, new_transport=i == 0)
