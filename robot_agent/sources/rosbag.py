"""ROS 2 recordings (rosbag2, SQLite3 or MCAP) in and out, with the pure-Python `rosbags`
library: no ROS installation needed.

In (`RosbagSource`, `vigil-robot run --source rosbag --source-path BAG`): one Observation per
message of the RGB topic (`sensor_msgs/msg/Image` rgb8/bgr8/rgba8/bgra8/mono8, or
`sensor_msgs/msg/CompressedImage`). Pose comes from the agent's pose estimator
(`MediaPipePose`, as for a video). The aligned depth topic (`sensor_msgs/msg/Image` 16UC1 in
millimetres or 32FC1 in metres, REP 118) is paired to each RGB frame by the nearest header stamp
within `tolerance_s`; a frame without a depth partner has no depth (the detector then treats
depth as missing, as for any source). Depth at the keypoints is sampled with the one
implementation, `vigil.depth.people_with_depth`, mapping the keypoints from the RGB picture's
size onto the depth picture's; `sensor_msgs/msg/CameraInfo` gives the intrinsics (K) which, with
the camera's height above the floor (`camera_height_m`, optional) and pitch, make the floor
measures with `vigil.floor`. Timestamps are the RGB header stamps (the bag's log time where a
stamp is 0) in seconds from the first RGB frame.

Out (`BagRecorder`, `vigil-robot run ... --record-bag OUT`): a new bag at OUT holding a copy of
the input bag's topics and, beside them, `/vigil/decision` (one `std_msgs/msg/String` JSON per
frame, at the frame's RGB log time) and `/vigil/behaviour` (one per behaviour change).
"""

from __future__ import annotations

import bisect
import json
import struct
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from robot_agent.sources.pacing import Pacer
from robot_agent.sources.replay import SourceError
from vigil.depth import people_with_depth
from vigil.floor import CameraMount, floor_measures_many
from vigil.observation import Observation
from vigil.skeleton import SkeletonFrame

DEFAULT_RGB_TOPIC = "/camera/color/image_raw"
DEFAULT_DEPTH_TOPIC = "/camera/aligned_depth_to_color/image_raw"
DEFAULT_INFO_TOPIC = "/camera/color/camera_info"
DEFAULT_DEPTH_TOLERANCE_S = 0.02
DECISION_TOPIC = "/vigil/decision"
BEHAVIOUR_TOPIC = "/vigil/behaviour"
STRING = "std_msgs/msg/String"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
_COLOUR = {
    "rgb8": (3, cv2.COLOR_RGB2BGR),
    "bgr8": (3, None),
    "rgba8": (4, cv2.COLOR_RGBA2BGR),
    "bgra8": (4, cv2.COLOR_BGRA2BGR),
    "mono8": (1, cv2.COLOR_GRAY2BGR),
}


class BagTopicError(SourceError):
    """The bag lacks a topic it needs (or has it with the wrong message type)."""


def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


@dataclass(slots=True)
class BagObservation(Observation):
    """An Observation that remembers the bag time (ns) of its RGB message, where the recorder
    writes this frame's decision."""

    bag_time_ns: int = 0


def _stamp_ns(raw: bytes | memoryview) -> int:
    """header.stamp of a CDR message that starts with a std_msgs/Header (Image, CameraInfo...),
    read from its first bytes without decoding the picture."""
    little = raw[1] == 1
    sec, nanosec = struct.unpack_from("<iI" if little else ">iI", raw, 4)
    return sec * 1_000_000_000 + nanosec


def colour_picture(message, msgtype: str, topic: str) -> np.ndarray:
    """An Image or CompressedImage message -> (H, W, 3) uint8 BGR."""
    if msgtype == COMPRESSED:
        picture = cv2.imdecode(np.frombuffer(message.data, np.uint8), cv2.IMREAD_COLOR)
        if picture is None:
            raise SourceError(f"{topic}: a CompressedImage ({message.format}) does not decode")
        return picture
    encoding = message.encoding.lower()
    if encoding not in _COLOUR:
        raise SourceError(f"{topic}: encoding {message.encoding!r} is not one of {list(_COLOUR)}")
    channels, conversion = _COLOUR[encoding]
    rows = np.asarray(message.data, np.uint8).reshape(message.height, message.step)
    picture = rows[:, : message.width * channels].reshape(message.height, message.width, channels)
    return (
        np.ascontiguousarray(picture) if conversion is None else cv2.cvtColor(picture, conversion)
    )


def depth_picture_mm(message, topic: str) -> np.ndarray:
    """A depth Image (16UC1/mono16 millimetres, 32FC1 metres) -> (H, W) uint16 millimetres, 0
    where there is no reading (what `vigil.depth.sample_depth` takes, scale 1.0)."""
    encoding = message.encoding.upper()
    order = ">" if message.is_bigendian else "<"
    if encoding in ("16UC1", "MONO16"):
        dtype, size = np.dtype(f"{order}u2"), 2
    elif encoding == "32FC1":
        dtype, size = np.dtype(f"{order}f4"), 4
    else:
        raise SourceError(f"{topic}: depth encoding {message.encoding!r}; expected 16UC1 or 32FC1")
    raw = np.asarray(message.data, np.uint8).reshape(message.height, message.step)
    values = raw[:, : message.width * size].copy().view(dtype).reshape(message.height, -1)
    if encoding == "32FC1":
        mm = np.nan_to_num(values.astype(np.float64) * 1000.0, nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(np.rint(mm), 0, 65535).astype(np.uint16)
    return values.astype(np.uint16)


def _open_reader(path: Path):
    from rosbags.rosbag2 import Reader

    if not path.exists():
        raise SourceError(f"rosbag {path} does not exist")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as error:  # rosbags raises ReaderError and others for what is not a bag
        raise SourceError(f"rosbag {path}: cannot be read as a rosbag2 ({error})") from error
    return reader


class RosbagSource:
    """The RGB topic of a rosbag2, frame by frame, through the pose estimator (module doc).

    depth_topic / info_topic None or "": no depth / no intrinsics. speed: 1 real time, 0 as fast
    as estimation goes. estimator: a factory of the pose estimator (default `MediaPipePose`).
    """

    generated = False

    def __init__(
        self,
        path: Path | str,
        rgb_topic: str = DEFAULT_RGB_TOPIC,
        depth_topic: str | None = DEFAULT_DEPTH_TOPIC,
        info_topic: str | None = DEFAULT_INFO_TOPIC,
        tolerance_s: float = DEFAULT_DEPTH_TOLERANCE_S,
        camera_height_m: float | None = None,
        camera_pitch_deg: float = 0.0,
        speed: float = 0.0,
        max_frames: int | None = None,
        estimator=None,
    ) -> None:
        self.path = Path(path)
        if tolerance_s < 0:
            raise SourceError(f"depth tolerance must not be negative, got {tolerance_s}")
        self.topics = {"rgb": rgb_topic, "depth": depth_topic or None, "info": info_topic or None}
        self.tolerance_ns = round(tolerance_s * 1e9)
        self.camera_height_m, self.camera_pitch_deg = camera_height_m, camera_pitch_deg
        self.speed, self.max_frames = speed, max_frames
        if estimator is None:
            from robot_agent.sources.mediapipe_video import MediaPipePose, load_mediapipe_pose

            load_mediapipe_pose()  # a missing extra fails now, not at the first frame

            def estimator():
                return MediaPipePose()

        self._estimator = estimator
        self.name = f"rosbag:{self.path.name}"
        self.typestore = typestore()
        reader = _open_reader(self.path)
        try:
            self._check_topics(reader)
            self.info = self._camera_info(reader) if self.topics["info"] else None
            self.depth_stamps = self._depth_index(reader) if self.topics["depth"] else []
            rgb = [_stamp_or(raw, ns) for _, ns, raw in reader.messages(self._conns(reader, "rgb"))]
        finally:
            reader.close()
        if not rgb:
            raise BagTopicError(f"rosbag {self.path}: topic {rgb_topic} has no messages")
        self.frame_count = len(rgb)
        span = (max(rgb) - min(rgb)) / 1e9
        self.fps = (len(rgb) - 1) / span if len(rgb) > 1 and span > 0 else 30.0
        self.frames_with_depth = 0

    # --- what the bag holds ------------------------------------------------------------------
    def _conns(self, reader, role: str) -> list:
        return [c for c in reader.connections if c.topic == self.topics[role]]

    def _check_topics(self, reader) -> None:
        present = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        wanted = {"rgb": (IMAGE, COMPRESSED), "depth": (IMAGE,), "info": (CAMERA_INFO,)}
        for role, types in wanted.items():
            topic = self.topics[role]
            if topic is None:
                continue
            conns = self._conns(reader, role)
            if not conns:
                raise BagTopicError(
                    f"rosbag {self.path}: no topic {topic} ({role}, {' or '.join(types)}); "
                    f"topics in the bag: {', '.join(present) or 'none'}"
                )
            bad = [c.msgtype for c in conns if c.msgtype not in types]
            if bad:
                raise BagTopicError(
                    f"rosbag {self.path}: topic {topic} ({role}) is {bad[0]}, expected "
                    f"{' or '.join(types)}"
                )

    def _camera_info(self, reader):
        for connection, _, raw in reader.messages(self._conns(reader, "info")):
            return self.typestore.deserialize_cdr(raw, connection.msgtype)
        raise BagTopicError(f"rosbag {self.path}: topic {self.topics['info']} has no messages")

    def _depth_index(self, reader) -> list[tuple[int, int]]:
        """(header stamp, log time) of every depth message, by stamp."""
        messages = reader.messages(self._conns(reader, "depth"))
        return sorted((_stamp_or(raw, ns), ns) for _, ns, raw in messages)

    def intrinsics(self, image_size: tuple[int, int]) -> tuple[float, float, float, float] | None:
        """(fx, fy, cx, cy) of CameraInfo.K scaled to a picture of `image_size` (width, height)
        (CameraInfo tells the size it was calibrated at)."""
        if self.info is None:
            return None
        k = np.asarray(self.info.k, np.float64)
        sx = image_size[0] / self.info.width if self.info.width else 1.0
        sy = image_size[1] / self.info.height if self.info.height else 1.0
        return k[0] * sx, k[4] * sy, k[2] * sx, k[5] * sy

    def __len__(self) -> int:
        return self.frame_count

    # --- frames ------------------------------------------------------------------------------
    def _depth_near(self, reader, stamp: int) -> np.ndarray | None:
        if not self.depth_stamps:
            return None
        at = bisect.bisect_left(self.depth_stamps, (stamp, -1))
        near = [self.depth_stamps[i] for i in (at - 1, at) if 0 <= i < len(self.depth_stamps)]
        best = min(near, key=lambda pair: abs(pair[0] - stamp))
        if abs(best[0] - stamp) > self.tolerance_ns:
            return None
        for connection, ns, raw in reader.messages(
            self._conns(reader, "depth"), best[1], best[1] + 1
        ):
            if _stamp_or(raw, ns) == best[0]:
                message = self.typestore.deserialize_cdr(raw, connection.msgtype)
                return depth_picture_mm(message, connection.topic)
        return None

    def _with_depth(self, observation: Observation, depth: np.ndarray, size) -> list[SkeletonFrame]:
        observation.depth_image = depth
        people = people_with_depth(observation, keypoint_image_size=size)
        # Sampled here, at the RGB picture's size: the detector must not sample it again.
        observation.depth_image = None
        fxy = self.intrinsics(size)
        if self.camera_height_m is None or fxy is None or not people:
            return people
        mount = CameraMount(*fxy, self.camera_height_m, self.camera_pitch_deg)
        floor = floor_measures_many(
            np.stack([p.keypoints for p in people]), np.stack([p.depth for p in people]), mount
        )
        return [
            SkeletonFrame(p.keypoints, p.depth, p.timestamp, f)
            for p, f in zip(people, floor, strict=True)
        ]

    def __iter__(self) -> Iterator[Observation]:
        reader = _open_reader(self.path)
        pose = self._estimator()
        pacer = Pacer(self.speed)
        first: int | None = None
        try:
            rgb = reader.messages(self._conns(reader, "rgb"))
            for index, (connection, log_ns, raw) in enumerate(rgb):
                if self.max_frames is not None and index >= self.max_frames:
                    break
                stamp = _stamp_or(raw, log_ns)
                first = stamp if first is None else first
                timestamp = (stamp - first) / 1e9
                message = self.typestore.deserialize_cdr(raw, connection.msgtype)
                image = colour_picture(message, connection.msgtype, connection.topic)
                observation = BagObservation(
                    timestamp=timestamp,
                    people=pose.people(image, timestamp),
                    index=index,
                    rgb=image,
                    bag_time_ns=log_ns,
                )
                depth = self._depth_near(reader, stamp)
                if depth is not None:
                    self.frames_with_depth += 1
                    size = (image.shape[1], image.shape[0])
                    observation.people = self._with_depth(observation, depth, size)
                pacer.wait(timestamp)
                yield observation
        finally:
            pose.close()
            reader.close()


def _stamp_or(raw, log_ns: int) -> int:
    """The message's header stamp, or its log time when the stamp is 0 (not set)."""
    stamp = _stamp_ns(raw)
    return stamp if stamp > 0 else log_ns


class BagRecorder:
    """Writes the agent's decisions and behaviour changes as a new bag (module doc). Frame
    listener of the pipeline (`on_frame`) and listener of the behaviour (`on_behaviour`);
    `close()` finishes the bag (its metadata): until then ROS tools cannot open it."""

    def __init__(self, out: Path | str, input_bag: Path | str | None = None) -> None:
        from rosbags.rosbag2 import Writer

        self.out = Path(out)
        if self.out.exists():
            raise SourceError(f"record bag {self.out} exists already; name a new directory")
        self.typestore = typestore()
        self.writer = Writer(self.out, version=8)
        self.writer.open()
        self.copied = self._copy(Path(input_bag)) if input_bag is not None else 0
        self._decision = self.writer.add_connection(
            DECISION_TOPIC, STRING, typestore=self.typestore
        )
        self._behaviour = self.writer.add_connection(
            BEHAVIOUR_TOPIC, STRING, typestore=self.typestore
        )
        self._pending: list[dict] = []
        self._last_ns = time.time_ns()
        self.decisions = self.behaviour_changes = 0
        self.closed = False

    def _copy(self, path: Path) -> int:
        """Every message of the input bag, as it was (raw CDR)."""
        reader = _open_reader(path)
        copied = 0
        try:
            mapping = {}
            for c in reader.connections:
                ext = c.ext
                known = c.msgtype in self.typestore.types
                mapping[c.id] = self.writer.add_connection(
                    c.topic,
                    c.msgtype,
                    typestore=self.typestore if known else None,
                    msgdef=None if known else c.msgdef.data,
                    rihs01=None if known else c.digest,
                    serialization_format=ext.serialization_format,
                    offered_qos_profiles=ext.offered_qos_profiles,
                )
            for connection, ns, raw in reader.messages():
                self.writer.write(mapping[connection.id], ns, raw)
                copied += 1
        finally:
            reader.close()
        return copied

    def _write(self, connection, ns: int, document: dict) -> None:
        message = self.typestore.types[STRING](data=json.dumps(document, separators=(",", ":")))
        self.writer.write(connection, ns, self.typestore.serialize_cdr(message, STRING))

    def on_frame(self, observation: Observation, result, transport_id: str | None) -> None:
        if self.closed:
            return
        ns = getattr(observation, "bag_time_ns", 0) or round(observation.timestamp * 1e9)
        self._last_ns = ns
        for change in self._pending:  # behaviour changes of this frame: at its time
            self._write(self._behaviour, ns, change)
        self._pending.clear()
        classification = result.classification
        self._write(
            self._decision,
            ns,
            {
                "frame": observation.index,
                "ts": observation.timestamp,
                "seq": result.seq,
                "transport_id": transport_id,
                "seen": result.seen,
                "decision": None if result.decision is None else result.decision.value,
                "raw_decision": None
                if classification is None
                else classification.raw_decision.value,
                "scores": None
                if classification is None
                else {k.value: v for k, v in classification.scores.items()},
                "model_version": None if classification is None else classification.model_version,
            },
        )
        self.decisions += 1

    def on_behaviour(self, change) -> None:
        if self.closed:
            return
        self._pending.append(change.as_dict())
        self.behaviour_changes += 1

    def close(self) -> None:
        if self.closed:
            return
        for change in self._pending:
            self._write(self._behaviour, self._last_ns, change)
        self._pending.clear()
        self.closed = True
        self.writer.close()
