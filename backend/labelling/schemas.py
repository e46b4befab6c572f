"""Request and response bodies of the labelling API."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.models._types import MAX_DB_INT
from backend.models.annotations import SegmentSource, SegmentStatus
from backend.models.videos import Split
from vigil.classes import Decision, TransportMode


class LabellingVideoOut(BaseModel):
    id: int
    name: str
    source: str
    generated: bool
    mode: TransportMode
    camera: str | None
    location: str | None
    person: str | None
    split: Split
    fps: float
    frame_count: int
    image_width: float | None
    image_height: float | None
    has_rgb: bool
    has_depth: bool
    labelled_frames: int
    segment_counts: dict[str, int]
    unreviewed: int
    status: Literal["unlabelled", "in_progress", "in_review", "done"]


class VideoPatch(BaseModel):
    split: Split | None = None
    person: str | None = Field(default=None, max_length=64)
    location: str | None = Field(default=None, max_length=128)
    camera: str | None = Field(default=None, max_length=64)


class Facets(BaseModel):
    persons: list[str]
    locations: list[str]
    cameras: list[str]
    sources: list[str]


class SegmentIn(BaseModel):
    first_frame: int = Field(ge=0, le=MAX_DB_INT, description="exact frame number (inclusive)")
    last_frame: int = Field(ge=0, le=MAX_DB_INT, description="exact frame number (inclusive)")
    label_key: str = Field(min_length=1, max_length=64)
    source: Literal["annotator", "model_suggestion"] = "annotator"


class SegmentPatch(BaseModel):
    first_frame: int | None = Field(default=None, ge=0, le=MAX_DB_INT)
    last_frame: int | None = Field(default=None, ge=0, le=MAX_DB_INT)
    label_key: str | None = Field(default=None, min_length=1, max_length=64)


class SegmentOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    video_id: int
    first_frame: int
    last_frame: int
    label_key: str
    label_name: str | None = None
    decision: Decision | None = None  # class of the label in the video's mode
    taxonomy_version: int
    status: SegmentStatus
    source: SegmentSource
    priority: int
    annotator: str | None = None
    reviewer: str | None = None
    review_comment: str | None
    alarm_id: int | None
    model_version: str | None
    created_at: datetime
    updated_at: datetime


class StatusAction(BaseModel):
    action: Literal["submit", "withdraw", "reopen"]
    comment: str | None = Field(default=None, max_length=2000)


class ReviewIn(BaseModel):
    decision: Literal["accept", "reject"]
    comment: str | None = Field(default=None, max_length=2000)


class SubmitAllOut(BaseModel):
    submitted: list[int]


class SegmentEventOut(BaseModel):
    at: datetime
    actor: str | None
    action: str
    snapshot: dict
    comment: str | None


class QueueItemOut(BaseModel):
    segment: SegmentOut
    video_name: str
    rank: int
    reason: str


class LabelAgreementOut(BaseModel):
    label_key: str
    kappa: float | None
    frames_a: int
    frames_b: int


class StageTimingOut(BaseModel):
    label_key: str
    onset_a_ms: float | None
    onset_b_ms: float | None
    onset_diff_ms: float | None
    offset_a_ms: float | None
    offset_b_ms: float | None
    offset_diff_ms: float | None


class AgreementOut(BaseModel):
    video_id: int
    annotator_a: str
    annotator_b: str
    frames_compared: int
    overall_kappa: float | None
    labels: list[LabelAgreementOut]
    stages: list[StageTimingOut]


class AnnotatorsOut(BaseModel):
    annotators: list[str]


class SuggestionOut(BaseModel):
    first_frame: int
    last_frame: int
    label_key: str


class ProbabilityOut(BaseModel):
    video_id: int
    source: Literal["stored", "model", "none"]
    model_version: str | None
    threshold: float | None
    probability: list[float | None]
    suggestions: list[SuggestionOut]
    error: str | None = None


class ImportOut(BaseModel):
    videos: list[str]
    segments: int = Field(description="segments the import created")
    already_there: int = Field(
        default=0, description="labels of the file the video held already (merge: not added)"
    )
    replaced: int = Field(default=0, description="imported segments under review it withdrew")


class View3DOut(BaseModel):
    url: str
    frames_shown: list[int]
    centre_frame: int = Field(description="the frame with depth nearest to the requested one")
