"""A directory of OpenPose JSON files (``openpose --write_json``: one file per frame,
``<name>_<frame:012d>_keypoints.json``), optionally with a directory of 16-bit depth PNGs.

Frames are ordered and numbered by the last run of digits in each file name; a depth PNG is
matched to a frame by the same rule (``fall-01-cam0-d-002.png`` is frame 2), and a frame
without one simply has no depth image. Keypoints are in pixels, as OpenPose writes them.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

from robot_agent.sources.pacing import Pacer
from robot_agent.sources.replay import SourceError, depth_files, frame_number, read_depth_png
from vigil.formats.openpose import from_openpose_json
from vigil.observation import Observation


class OpenPoseDirSource:
    """One Observation per JSON file; timestamps are frame_number / fps from the first frame.

    depth_scale_mm: raw depth value -> millimetres (1.0 for the usual 16-bit millimetre PNGs;
    URFD fall sequences: 6000 / 65535). speed: 1 real time, 0 as fast as possible.
    """

    generated = False

    def __init__(
        self,
        directory: Path | str,
        fps: float = 30.0,
        depth_dir: Path | str | None = None,
        depth_scale_mm: float = 1.0,
        speed: float = 0.0,
    ) -> None:
        self.directory = Path(directory)
        if not self.directory.is_dir():
            raise SourceError(f"openpose directory {self.directory} does not exist")
        if fps <= 0:
            raise SourceError(f"fps must be positive, got {fps}")
        if depth_scale_mm <= 0:
            raise SourceError(f"depth_scale_mm must be positive, got {depth_scale_mm}")
        self.name = f"openpose:{self.directory.name}"
        self.fps = fps
        self.speed = speed
        self.depth_scale_mm = depth_scale_mm
        self.depth = depth_files(depth_dir) if depth_dir is not None else {}
        numbered = []
        for path in self.directory.glob("*.json"):
            number = frame_number(path.with_name(path.name.replace("_keypoints", "")))
            if number is None:
                raise SourceError(f"{path}: no frame number in the file name")
            numbered.append((number, path))
        if not numbered:
            raise SourceError(f"openpose directory {self.directory} holds no .json files")
        numbered.sort()
        self.files = numbered

    def __len__(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[Observation]:
        pacer = Pacer(self.speed)
        first = self.files[0][0]
        for number, path in self.files:
            timestamp = (number - first) / self.fps
            try:
                document = json.loads(path.read_text())
                people = from_openpose_json(document, timestamp)
            except (OSError, json.JSONDecodeError, ValueError, AttributeError) as error:
                raise SourceError(f"{path}: {error}") from error
            pacer.wait(timestamp)
            depth_path = self.depth.get(number)
            yield Observation(
                timestamp=timestamp,
                people=people,
                index=number,
                depth_image=read_depth_png(depth_path) if depth_path is not None else None,
                depth_scale_mm=self.depth_scale_mm,
            )
