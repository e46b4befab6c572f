"""OpenPose JSON directories with 16-bit depth pictures, and the import CLI.

The JSON files and depth pictures here are generated test input (OpenPose output for a real
recording is not in the repository)."""

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
from sqlalchemy import select

from backend.db import transaction
from backend.labelling.errors import LabellingError
from backend.labelling.importers.openpose import import_openpose_dir
from backend.models.videos import Frame, Video
from vigil.skeleton import decode_depth, decode_keypoints


def _write_openpose(directory, frames=4):
    directory.mkdir()
    for n in range(frames):
        person = np.zeros((25, 3))
        person[0] = (100 + n, 50, 0.9)  # nose
        person[1] = (100 + n, 80, 0.8)  # neck
        weak = np.zeros((25, 3))
        weak[0] = (300, 300, 0.1)
        document = {
            "version": 1.3,
            "people": [
                {"pose_keypoints_2d": weak.ravel().tolist()},
                {"pose_keypoints_2d": person.ravel().tolist()},
            ],
        }
        (directory / f"clip_{n + 10:012d}_keypoints.json").write_text(json.dumps(document))


def test_openpose_directory_with_depth(tmp_path, session_factory):
    _write_openpose(tmp_path / "json")
    depth_dir = tmp_path / "depth"
    depth_dir.mkdir()
    picture = np.full((240, 320), 2500, np.uint16)  # 2.5 m at 1 mm per unit
    cv2.imwrite(str(depth_dir / "depth_000000000011.png"), picture)
    with transaction(session_factory) as session:
        video = import_openpose_dir(session, tmp_path / "json", "op-1", depth_dir=depth_dir)
        video_id = video.id
    with session_factory() as session:
        video = session.get(Video, video_id)
        assert video.frame_count == 4 and video.image_width == 320
        frames = session.scalars(
            select(Frame).where(Frame.video_id == video_id).order_by(Frame.index)
        ).all()
    assert [f.index for f in frames] == [0, 1, 2, 3]
    keypoints = decode_keypoints(frames[1].keypoints)
    assert tuple(keypoints[0]) == pytest.approx((101, 50, 0.9))  # the confident person
    assert frames[0].depth is None
    depth = decode_depth(frames[1].depth)
    assert depth[0] == pytest.approx(2.5) and np.isnan(depth[2])


def test_openpose_errors_name_the_problem(tmp_path, session_factory):
    (tmp_path / "empty").mkdir()
    with (
        transaction(session_factory) as session,
        pytest.raises(LabellingError, match="no OpenPose"),
    ):
        import_openpose_dir(session, tmp_path / "empty", "x")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "f_000000000001_keypoints.json").write_text('{"people": [{"pose_keypoints_2d": [1]}]}')
    with transaction(session_factory) as session, pytest.raises(LabellingError, match="75"):
        import_openpose_dir(session, bad, "y")


def test_cli_imports_urfd_idempotently_and_names_bad_input(database_url, tmp_path):
    env = {"VIGIL_DATABASE_URL": database_url, "PATH": "/usr/bin:/bin"}
    command = [sys.executable, "-m", "backend.labelling.cli"]
    first = subprocess.run(
        [*command, "import-urfd", "--only", "adl-02"], env=env, capture_output=True, text=True
    )
    assert first.returncode == 0, first.stderr
    assert "1 videos imported" in first.stdout
    again = subprocess.run(
        [*command, "import-urfd", "--only", "adl-02"], env=env, capture_output=True, text=True
    )
    assert "0 videos imported" in again.stdout and "1 already there" in again.stdout
    missing = subprocess.run(
        [*command, "import-export", str(tmp_path / "nope.json")],
        env=env,
        capture_output=True,
        text=True,
    )
    assert missing.returncode == 2 and "file:" in missing.stderr
