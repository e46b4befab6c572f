"""What an imported file may hold, checked at the door: every value that a later endpoint reads
(export, the 3D view, the facets) is of its type, finite and in range, or the import is refused
with a 422 naming the field. Types are strict: "abc" (or "640") is not a width, a list is not
a camera, a string is not a set of intrinsics.

The documents come from `json.loads` (Python objects), so the strictness is set per field:
enums still read their string values.
"""

from __future__ import annotations

import re
from functools import cache
from typing import Annotated, TypeVar

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from backend.labelling.errors import LabellingError
from backend.models._types import MAX_DB_INT
from backend.models.annotations import SegmentStatus
from backend.models.videos import Split
from vigil.classes import TransportMode

#: C0 and C1 control characters and the Unicode line and paragraph separators: in a name they
#: break headers (CR/LF ends a header line), CSV rows and log lines.
CONTROL_CHARACTERS = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")
FLOAT32_MAX = float(np.finfo(np.float32).max)
MAX_IMAGE_SIDE = 1_000_000.0  # pixels; far beyond any camera
MAX_FPS = 1000.0


def check_text(value: str) -> str:
    found = CONTROL_CHARACTERS.search(value)
    if found:
        raise ValueError(f"must not contain control characters (found U+{ord(found[0]):04X})")
    return value


def check_name(value: str) -> str:
    check_text(value)
    if not value.strip():
        raise ValueError("must not be blank")
    return value


def video_name(value: str, field: str = "name") -> str:
    """A new video's name (the `name` query parameter), or LabellingError naming `field`."""
    try:
        return check_name(value)
    except ValueError as error:
        raise LabellingError(f"{field}: {error}") from None


def _text(max_length: int):
    return Annotated[str, Field(max_length=max_length), AfterValidator(check_text)]


Name = Annotated[str, Field(min_length=1, max_length=128), AfterValidator(check_name)]
StrictInt = Annotated[int, Field(strict=True)]
FrameNumber = Annotated[int, Field(strict=True, ge=0, le=MAX_DB_INT)]
Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Float32 = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=-FLOAT32_MAX, le=FLOAT32_MAX)]
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0, le=MAX_IMAGE_SIDE)]
ImageSide = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0, le=MAX_IMAGE_SIDE)]


class _Loose(BaseModel):
    """Fields not listed are ignored (an export carries frame_count, annotator...)."""

    model_config = ConfigDict(extra="ignore")


class Intrinsics(_Loose):
    """Pinhole camera in pixels (the 3D view divides by fx and fy)."""

    fx: Positive
    fy: Positive
    cx: Finite
    cy: Finite


class VideoMeta(_Loose):
    name: Name | None = None
    source: _text(32) | None = None
    generated: Annotated[bool, Field(strict=True)] = False
    mode: TransportMode = TransportMode.WALKING
    camera: _text(64) | None = None
    location: _text(128) | None = None
    person: _text(64) | None = None
    fps: Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0, le=MAX_FPS)] | None = None
    split: Split | None = None
    image_width: ImageSide | None = None  # 0 (or null): keypoints are normalised
    image_height: ImageSide | None = None
    intrinsics: Intrinsics | None = None


class FrameHead(_Loose):
    """A Vigil JSON frame's number and time (its arrays are checked by exchange._numbers)."""

    index: Annotated[int, Field(strict=True, ge=0)]  # store.add_video bounds it (MAX_FRAMES)
    ts: Finite


class SegmentRecord(_Loose):
    first_frame: FrameNumber
    last_frame: FrameNumber
    label_key: Annotated[str, Field(min_length=1, max_length=64), AfterValidator(check_text)]
    status: SegmentStatus = SegmentStatus.ACCEPTED
    review_comment: _text(2000) | None = None


class CocoImage(_Loose):
    id: Annotated[int, Field(strict=True, ge=1, le=MAX_DB_INT)]
    frame_index: FrameNumber | None = None
    label_key: _text(64) | None = None


class CocoAnnotation(_Loose):
    image_id: StrictInt
    keypoints: Annotated[list[Float32], Field(min_length=51, max_length=51)]


T = TypeVar("T")


@cache
def _adapter(kind) -> TypeAdapter:
    return TypeAdapter(kind)


def validated(kind: type[T], value: object, where: str) -> T:
    """`value` as `kind` (a model or a list of one), or LabellingError naming the field:
    'video.fps: Input should be a finite number', 'frames[3].ts: ...'."""
    try:
        return _adapter(kind).validate_python(value)
    except ValidationError as error:
        first = error.errors()[0]
        path = where
        for part in first["loc"]:
            path += f"[{part}]" if isinstance(part, int) else f".{part}"
        raise LabellingError(f"{path.lstrip('.')}: {first['msg']}") from None
