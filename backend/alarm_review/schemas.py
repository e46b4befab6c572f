from datetime import datetime
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.alarms.schemas import AlarmOut


class ReplayFrameOut(BaseModel):
    seq: int | None
    index: int
    ts: float
    keypoints: list[list[float]]
    depth: list[float | None] | None
    decision: str | None
    scores: dict[str, float]
    model_version: str | None


class AlarmReplayOut(BaseModel):
    alarm: AlarmOut
    before_s: float
    after_s: float
    generated: bool = Field(description="the frames are generated (simulation), not a real camera")
    frames: list[ReplayFrameOut]


class AlarmPageOut(BaseModel):
    total: int
    items: list[AlarmOut]


class ShiftRow(BaseModel):
    shift_start: datetime
    shift: Literal["early", "late", "night"]
    ward: str
    alarms: int
    emergencies: int
    resolved: int
    false_alarms: int
    acknowledged: int
    unacknowledged: int
    median_ack_s: float | None = Field(
        description="over acknowledged and unacknowledged alarms; an unacknowledged one counts"
        " the time until it was resolved or the period ended"
    )


class ModelRow(BaseModel):
    model_version: str | None
    alarms: int
    resolved: int
    false_alarms: int
    false_share: float | None
    acknowledged: int
    unacknowledged: int
    median_ack_s: float | None = Field(
        description="over acknowledged and unacknowledged alarms; an unacknowledged one counts"
        " the time until it was resolved or the period ended"
    )


class FatigueOut(BaseModel):
    since: datetime
    until: datetime
    shifts: list[ShiftRow]
    by_model: list[ModelRow]


class ReviewItemOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    video_id: int
    first_frame: int
    last_frame: int
    label_key: str
    taxonomy_version: int
    status: str
    source: str
    priority: int
    alarm_id: int | None
    model_version: str | None
    review_comment: str | None
    created_at: datetime
