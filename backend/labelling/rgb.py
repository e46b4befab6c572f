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
    """Decoded RGB frames per (clip, frame number), least recently used dropped first."""

    def __init__(self, max_frames: int = 600) -> None:
        self.max_frames = max_frames
        self._frames: OrderedDict[tuple[str, int], np.ndarray] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

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

    def _decode_through(self, path: str, number: int) -> None:
        """Decode from the start of the clip up to `number` (+ a little read-ahead), caching."""
        if not Path(path).is_file():
            raise NotFound(f"rgb: clip {Path(path).name} is missing on the server")
        capture = cv2.VideoCapture(path)
        try:
            if not capture.isOpened():
                raise LabellingError(f"rgb: cannot open clip {Path(path).name}")
            read_ahead = number + 30
            index = 0
            while index <= read_ahead:
                ok, picture = capture.read()
                if not ok:
                    break
                if index >= number - 30:
                    self._put((path, index), picture)
                index += 1
        finally:
            capture.release()

    def _put(self, key: tuple[str, int], picture: np.ndarray) -> None:
        self._frames[key] = picture
        self._frames.move_to_end(key)
        while len(self._frames) > self.max_frames:
            self._frames.popitem(last=False)


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
