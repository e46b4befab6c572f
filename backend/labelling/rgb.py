"""RGB frames of a recording's clip, decoded server-side by exact frame number.

Frames are read sequentially from the clip (never by the codec's approximate seek), kept in
an LRU cache of decoded pictures, and the patient's head is blurred using the face keypoints.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

from backend.labelling.errors import LabellingError, NotFound
from vigil.skeleton import INDEX

FACE = [INDEX[n] for n in ("nose", "r_eye", "l_eye", "r_ear", "l_ear")]
SHOULDERS = [INDEX["r_shoulder"], INDEX["l_shoulder"]]
NECK = INDEX["neck"]
MIN_HEAD_RADIUS = 12.0  # pixels of the RGB picture


class FrameCache:
    """Decoded RGB frames per (clip, frame number), least recently used dropped first.

    Each clip keeps a reader open at its decode position, so playing forward decodes each frame
    once; a request behind the reader reopens the clip and decodes from its start (exact, never
    the codec's approximate seek).
    """

    READ_AHEAD = 30
    MAX_READERS = 4

    def __init__(self, max_frames: int = 600) -> None:
        self.max_frames = max_frames
        self._frames: OrderedDict[tuple[str, int], np.ndarray] = OrderedDict()
        self._readers: OrderedDict[str, tuple[cv2.VideoCapture, int]] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0
        self.decoded = 0

    def get(self, path: str, number: int) -> np.ndarray:
        key = (path, number)
        with self._lock:
            if key in self._frames:
                self._frames.move_to_end(key)
                self.hits += 1
                return self._frames[key]
            self.misses += 1
            self._decode_through(path, number)
            if key not in self._frames:
                raise NotFound(f"frame: clip has no frame {number}")
            return self._frames[key]

    def _reader(self, path: str, number: int) -> tuple[cv2.VideoCapture, int]:
        if path in self._readers:
            capture, position = self._readers.pop(path)
            if position <= number:
                return capture, position
            capture.release()
        if not Path(path).is_file():
            raise NotFound(f"rgb: clip {Path(path).name} is missing on the server")
        capture = cv2.VideoCapture(path)
        if not capture.isOpened():
            raise LabellingError(f"rgb: cannot open clip {Path(path).name}")
        return capture, 0

    def _decode_through(self, path: str, number: int) -> None:
        """Decode up to `number` plus a read-ahead, caching the frames around `number`."""
        capture, position = self._reader(path, number)
        while position <= number + self.READ_AHEAD:
            ok, picture = capture.read()
            if not ok:
                break
            self.decoded += 1
            if position >= number - self.READ_AHEAD:
                self._put((path, position), picture)
            position += 1
        self._readers[path] = (capture, position)
        while len(self._readers) > self.MAX_READERS:
            _, (old, _) = self._readers.popitem(last=False)
            old.release()

    def _put(self, key: tuple[str, int], picture: np.ndarray) -> None:
        self._frames[key] = picture
        self._frames.move_to_end(key)
        while len(self._frames) > self.max_frames:
            self._frames.popitem(last=False)

    def close(self) -> None:
        with self._lock:
            for capture, _ in self._readers.values():
                capture.release()
            self._readers.clear()


class JpegCache:
    """Finished pictures (blurred or not) per (video, frame, blur): a repeat is a lookup."""

    def __init__(self, max_items: int = 1000) -> None:
        self.max_items = max_items
        self._items: OrderedDict[tuple[int, int, bool], bytes] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple[int, int, bool]) -> bytes | None:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
            return None

    def put(self, key: tuple[int, int, bool], data: bytes) -> None:
        with self._lock:
            self._items[key] = data
            self._items.move_to_end(key)
            while len(self._items) > self.max_items:
                self._items.popitem(last=False)


def crop(picture: np.ndarray, region: dict | None) -> np.ndarray:
    if not region:
        return picture
    x, y, w, h = (int(region[k]) for k in ("x", "y", "width", "height"))
    return picture[y : y + h, x : x + w]


def head_circle(keypoints: np.ndarray, scale_x: float, scale_y: float):
    """(cx, cy, radius) in picture pixels, or None when no face or shoulder keypoint is seen."""
    points = keypoints.copy()
    points[:, 0] *= scale_x
    points[:, 1] *= scale_y
    face = points[FACE][points[FACE][:, 2] > 0][:, :2]
    shoulders = points[SHOULDERS][points[SHOULDERS][:, 2] > 0][:, :2]
    shoulder_width = (
        float(np.linalg.norm(shoulders[0] - shoulders[1])) if len(shoulders) == 2 else 0.0
    )
    if len(face):
        centre = face.mean(axis=0)
        spread = float(np.max(np.linalg.norm(face - centre, axis=1))) if len(face) > 1 else 0.0
    elif points[NECK, 2] > 0 and shoulder_width > 0:
        # No face keypoint: the head sits above the neck by about half a shoulder width.
        centre = points[NECK, :2] - np.array([0.0, 0.6 * shoulder_width])
        spread = 0.0
    else:
        return None
    radius = max(1.6 * spread, 0.55 * shoulder_width, MIN_HEAD_RADIUS)
    return float(centre[0]), float(centre[1]), radius


def blur_head(picture: np.ndarray, keypoints: np.ndarray | None, scale: tuple[float, float]):
    """Blur a disc around the head; without any usable keypoint blur the whole picture
    (the safe default: a face is never shown because its keypoints were missed)."""
    circle = head_circle(keypoints, *scale) if keypoints is not None else None
    size = max(picture.shape[:2]) // 8 * 2 + 1
    blurred = cv2.GaussianBlur(picture, (size, size), 0)
    if circle is None:
        return blurred
    cx, cy, radius = circle
    mask = np.zeros(picture.shape[:2], np.uint8)
    cv2.circle(mask, (int(round(cx)), int(round(cy))), int(round(radius)), 255, -1)
    out = picture.copy()
    out[mask > 0] = blurred[mask > 0]
    return out


def encode_jpeg(picture: np.ndarray, quality: int = 85) -> bytes:
    ok, data = cv2.imencode(".jpg", picture, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise LabellingError("rgb: could not encode the frame")
    return data.tobytes()
