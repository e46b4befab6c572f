"""Keypoint sources: OpenPose directory, URFD and Vigil-export replay, simulator, pacing."""

import json

import cv2
import numpy as np
import pytest

from robot_agent.sources.openpose_dir import OpenPoseDirSource
from robot_agent.sources.pacing import Pacer
from robot_agent.sources.replay import SourceError, UrfdReplaySource, VigilExportSource
from robot_agent.sources.simulator import SimulatorSource
from vigil.datasets import urfd
from vigil.skeleton import N_KEYPOINTS
from vigil.synthetic import generate_transport


def assert_keypoint_source(source):
    """The KeypointSource protocol (not runtime-checkable): a name, an fps, iterable."""
    assert isinstance(source.name, str) and source.name
    assert isinstance(source.generated, bool)
    assert source.fps > 0
    assert callable(iter(source).__next__)


def _write_openpose_dir(tmp_path, frames=12):
    """What `openpose --write_json` writes, from a GENERATED two-person scene."""
    transport = generate_transport("walking", seed=2, duration_s=2, n_people=2)
    json_dir = tmp_path / "json"
    depth_dir = tmp_path / "depth"
    json_dir.mkdir()
    depth_dir.mkdir()
    expected = []
    for t in range(frames):
        people = transport.detections(t)
        doc = {
            "version": 1.3,
            "people": [
                {
                    "person_id": [-1],
                    "pose_keypoints_2d": p.keypoints.ravel().tolist(),
                    "face_keypoints_2d": [],
                    "hand_left_keypoints_2d": [],
                }
                for p in people
            ],
        }
        (json_dir / f"clip_{t:012d}_keypoints.json").write_text(json.dumps(doc))
        expected.append(people)
        if t % 3 == 0:  # depth for every third frame only, millimetres
            depth = np.full((480, 640), 2500 + t, np.uint16)
            cv2.imwrite(str(depth_dir / f"depth_{t:04d}.png"), depth)
    return json_dir, depth_dir, expected


def test_openpose_directory_with_depth(tmp_path):
    json_dir, depth_dir, expected = _write_openpose_dir(tmp_path)
    source = OpenPoseDirSource(json_dir, fps=30, depth_dir=depth_dir, depth_scale_mm=1.0)
    assert_keypoint_source(source)
    observations = list(source)
    assert len(observations) == len(source) == 12
    for t, obs in enumerate(observations):
        assert obs.index == t and obs.timestamp == pytest.approx(t / 30)
        assert len(obs.people) == len(expected[t])
        for got, want in zip(obs.people, expected[t], strict=True):
            present = want.keypoints[:, 2] > 0
            np.testing.assert_allclose(got.keypoints[present], want.keypoints[present], rtol=1e-6)
            assert (got.keypoints[~present] == 0).all()
        if t % 3 == 0:
            assert obs.depth_image.dtype == np.uint16 and obs.depth_image[0, 0] == 2500 + t
        else:
            assert obs.depth_image is None


def test_openpose_directory_bad_input_names_the_file(tmp_path):
    json_dir, _, _ = _write_openpose_dir(tmp_path, frames=3)
    bad = json_dir / "clip_000000000003_keypoints.json"
    bad.write_text(json.dumps({"people": [{"pose_keypoints_2d": [1, 2, 3]}]}))
    with pytest.raises(SourceError, match=r"clip_000000000003_keypoints\.json.*75 numbers"):
        list(OpenPoseDirSource(json_dir))
    bad.write_text("{not json")
    with pytest.raises(SourceError, match="clip_000000000003"):
        list(OpenPoseDirSource(json_dir))
    with pytest.raises(SourceError, match="does not exist"):
        OpenPoseDirSource(tmp_path / "nowhere")
    with pytest.raises(SourceError, match="no .json files"):
        OpenPoseDirSource(tmp_path / "depth")
    (tmp_path / "depth" / "x.png").write_bytes(cv2.imencode(".png", np.zeros((4, 4), np.uint8))[1])
    (tmp_path / "d2").mkdir()
    cv2.imwrite(str(tmp_path / "d2" / "f_0001.png"), np.zeros((4, 4), np.uint8))
    (json_dir / "clip_000000000003_keypoints.json").unlink()
    source = OpenPoseDirSource(json_dir, depth_dir=tmp_path / "d2")
    with pytest.raises(SourceError, match="16-bit"):
        list(source)


def test_urfd_replay_is_the_real_sequence_with_truth_and_depth():
    source = UrfdReplaySource("fall-01", speed=0, depth_dir=urfd.default_dir() / "depth")
    sequence = urfd.load(names=["fall-01"])[0]
    observations = list(source)
    assert len(observations) == len(sequence) == 160
    assert [bool(o.people) for o in observations] == sequence.detected.tolist()
    for obs, kp in zip(observations, sequence.keypoints, strict=True):
        if obs.people:
            np.testing.assert_array_equal(obs.people[0].keypoints, kp)
            assert obs.patient_hint == 0
    truth = [o.truth for o in observations]
    assert truth[0] == "walking" and truth[-1] == "lying_on_floor" and "falling" in truth
    assert source.depth_scale_mm == pytest.approx(6000 / 65535)
    with_depth = [o.index for o in observations if o.depth_image is not None]
    assert with_depth == [2, 10, 20, 30, 40, 50, 60, 70, 80, 90, 99]
    with pytest.raises(SourceError, match="no sequence 'fall-99'"):
        UrfdReplaySource("fall-99")


def test_replay_paces_real_time_and_faster():
    now = [0.0]
    slept = []

    def sleep(seconds):
        slept.append(seconds)
        now[0] += seconds

    pacer = Pacer(2.0, clock=lambda: now[0], sleep=sleep)
    for ts in (0.0, 1.0, 2.0):
        pacer.wait(ts)
    assert slept == pytest.approx([0.5, 0.5])
    fast = Pacer(0.0, clock=lambda: now[0], sleep=sleep)
    fast.wait(0.0)
    fast.wait(100.0)
    assert len(slept) == 2
    with pytest.raises(ValueError, match="speed"):
        Pacer(-1)


def _export_document():
    keypoints = np.zeros((N_KEYPOINTS, 3))
    keypoints[:, 0], keypoints[:, 1], keypoints[:, 2] = 300, np.arange(25) * 10, 0.8
    frames = []
    for i in range(6):
        depth = None if i % 2 else [2.5] * 24 + [None]
        kp = keypoints if i != 4 else np.zeros_like(keypoints)  # nobody found in frame 4
        frames.append({"index": i, "ts": i / 15, "keypoints": kp.tolist(), "depth": depth})
    return {
        "format": "vigil-labels",
        "version": 1,
        "taxonomy_version": 1,
        "video": {"name": "ward-7", "fps": 15, "generated": False, "image_width": 640},
        "frames": frames,
        "segments": [
            {"first_frame": 0, "last_frame": 3, "label_key": "walking", "status": "accepted"},
            {"first_frame": 3, "last_frame": 5, "label_key": "falling", "status": "accepted"},
        ],
    }


def test_vigil_export_replay(tmp_path):
    path = tmp_path / "ward-7.json"
    path.write_text(json.dumps(_export_document()))
    source = VigilExportSource(path, speed=0)
    assert source.fps == 15 and source.name == "export:ward-7"
    observations = list(source)
    assert [o.truth for o in observations] == ["walking"] * 3 + ["falling"] * 3
    assert [len(o.people) for o in observations] == [1, 1, 1, 1, 0, 1]
    assert observations[2].timestamp == pytest.approx(2 / 15)
    first = observations[0].people[0]
    assert first.depth[0] == pytest.approx(2.5) and np.isnan(first.depth[24])
    assert np.isnan(observations[1].people[0].depth).all()


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.update(format="coco"), "format must be 'vigil-labels'"),
        (lambda d: d.update(version=9), "version"),
        (lambda d: d["frames"][2].update(keypoints=[[1, 2, 3]]), r"frames\[2\]\.keypoints"),
        (lambda d: d["frames"][1].pop("index"), r"frames\[1\]: missing field 'index'"),
        (lambda d: d["frames"][0].update(depth=[1.0]), r"frames\[0\]\.depth"),
        (lambda d: d["segments"][1].update(last_frame=1), r"segments\[1\]\.last_frame"),
        (lambda d: d["video"].update(fps=-3), r"video\.fps"),
    ],
)
def test_vigil_export_bad_input_names_the_field(tmp_path, mutate, message):
    document = _export_document()
    mutate(document)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(SourceError, match=message):
        VigilExportSource(path)


def test_simulator_source_several_people_truth_and_back_to_back_transports():
    source = SimulatorSource("wheelchair", seed=4, duration_s=5, n_people=3, transports=2, speed=0)
    assert_keypoint_source(source)
    observations = list(source)
    first, second = source.transport(0), source.transport(1)
    assert len(observations) == first.n_frames + second.n_frames
    stamps = np.array([o.timestamp for o in observations])
    assert (np.diff(stamps) > 0).all()
    assert [o.index for o in observations] == list(range(len(observations)))
    assert [o.truth for o in observations] == first.labels + second.labels
    assert max(len(o.people) for o in observations) >= 2
    for obs in observations:
        if obs.patient_hint is not None:
            assert obs.people[obs.patient_hint].timestamp == obs.timestamp
    hinted = [o for o in observations if o.patient_hint is not None]
    assert len(hinted) > 0.9 * len(observations)
    assert source.generated and "generated" in source.name
    with pytest.raises(ValueError, match="n_people"):
        SimulatorSource(n_people=9)


def test_replay_source_path_takes_a_keypoint_file_in_urfds_format(tmp_path):
    from robot_agent.config import ConfigError, load_settings
    from robot_agent.source_factory import transports_for
    from tests.vigil.test_urfd import _keypoint_rows, _write

    header, rows = _keypoint_rows("adl-03")
    path = _write(tmp_path / "one.csv.gz", header, rows)
    for source_path in (str(path), f"{path}#adl-03"):
        settings = load_settings(None, source="replay", source_path=source_path)
        plan = next(transports_for(settings))
        assert plan.observations.name == "urfd:adl-03" and plan.fps == 30.0
        assert len(list(plan.observations)) == len(rows)
    settings = load_settings(None, source="replay", source_path=f"{path}#adl-99")
    with pytest.raises(ConfigError, match="source_path: .*no sequence 'adl-99'"):
        transports_for(settings)
    two = _write(tmp_path / "two.csv.gz", header, rows + _keypoint_rows("adl-04")[1])
    settings = load_settings(None, source="replay", source_path=str(two))
    with pytest.raises(ConfigError, match="holds 2 sequences; name one"):
        transports_for(settings)
