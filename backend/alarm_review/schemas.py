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
    missed: int = Field(default=0, description='Emergencies that ended up "missed: needs review"')
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
    missed: int = 0
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


class HandoverCounts(BaseModel):
    open: int
    missed: int = Field(description='now "missed: needs review"')
    acknowledged_unresolved: int
    resolved: int
    escalated: int
    ever_missed: int = Field(description="missed at some point (resolved since or not)")


class HandoverRobotRow(HandoverCounts):
    robot_id: str | None = Field(description="none for the ward system's own alarms")
    alarms: int


class HandoverFatigue(BaseModel):
    """Over the alarms raised during the shift."""

    alarms: int
    emergencies: int
    pauses: int
    technical: int
    resolved_with_verdict: int
    non_actionable: int = Field(description='resolved with the verdict "false alarm"')
    non_actionable_share: float | None = Field(
        description="non_actionable / resolved_with_verdict (None: no verdict yet)"
    )
    acknowledged: int
    unacknowledged: int
    escalated: int
    missed: int
    ack_p50_s: float | None = Field(
        description="time to acknowledge; an unacknowledged alarm counts the time until it was "
        "resolved or the period ended"
    )
    ack_p90_s: float | None
    ack_p95_s: float | None


class HandoverAlarm(BaseModel):
    section: Literal["open", "missed", "acknowledged", "resolved"]
    was_missed: bool
    alarm: AlarmOut


class HandoverOut(BaseModel):
    since: datetime
    until: datetime
    shift: Literal["early", "late", "night"] | None = Field(
        description="the shift [since, until) is, when it is exactly one"
    )
    ward: str | None
    counts: HandoverCounts
    per_robot: list[HandoverRobotRow]
    fatigue: HandoverFatigue
    alarms: list[HandoverAlarm] = Field(
        description="every alarm unresolved now and every alarm raised in the shift, newest first"
    )
