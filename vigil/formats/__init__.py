"""Converters from common pose formats into the canonical SkeletonFrame (BODY_25)."""

from vigil.formats.coco import (
    COCO17,
    MOVENET13,
    coco17_to_body25,
    from_coco17,
    from_movenet13,
    movenet13_to_body25,
)
from vigil.formats.mediapipe import MEDIAPIPE33, from_mediapipe33, mediapipe33_to_body25
from vigil.formats.openpose import from_openpose_json

__all__ = [
    "COCO17",
    "MEDIAPIPE33",
    "MOVENET13",
    "coco17_to_body25",
    "from_coco17",
    "from_mediapipe33",
    "from_movenet13",
    "from_openpose_json",
    "mediapipe33_to_body25",
    "movenet13_to_body25",
]
