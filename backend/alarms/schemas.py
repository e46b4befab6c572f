from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field, computed_field, model_validator

from backend.models.alarms import (
    AlarmKind,
    AlarmPriority,
    AlarmState,
    FalseAlarmReason,
    Verdict,
)
from vigil.classes import BehaviourState


def alarm_key(robot_id: str | None, transport_id: str | None, kind: str, ward: str = "") -> str:
    """An alarm's identity on the nurse board: at most one unresolved alarm per key (an alarm
    about no robot is its ward's)."""
    if robot_id is None:
        return f"ward:{ward}//{kind}"
    return f"{robot_id}/{transport_id or ''}/{kind}"


class DispositionOut(BaseModel):
    """What the alarm distribution reported of the alarm on a clinician's device."""

    model_config = ConfigDict(from_attributes=True)

    disposition: str = Field(description="delivered, read, accepted or rejected")
    clinician: str
    device: str
    at: datetime


class AlarmOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: AlarmKind
    priority: AlarmPriority
    state: AlarmState
    robot_id: str | None = Field(description="None: an alarm about no robot (its ward's)")
    ward: str
    transport_id: str | None
    patient: str | None
    location: str | None
    raised_at: datetime
    updated_at: datetime
    acknowledged_at: datetime | None
    acknowledged_by: str | None = None
    resolved_at: datetime | None
    resolved_by: str | None = None
    verdict: Verdict | None
    reason: FalseAlarmReason | None
    comment: str | None
    escalation_level: int
    escalated_to: str | None = Field(
        default=None,
        description="a missed Emergency: the last of the ward's further responders it reached",
    )
    robot_state: BehaviourState | None = Field(
        default=None, description="what the robot did about it, as it reported (last change)"
    )
    robot_state_since: datetime | None = None
    realarmed_at: datetime | None
    video_id: int | None
    first_seq: int | None
    last_seq: int | None
    decision_count: int
    model_version: str | None
    threshold: float | None
    delay_ms: int | None
    details: dict | None = Field(
        default=None,
        description="technical alarms: what it is about (detection_degraded: missing_inputs, "
        "reason, assigned_model, running_model, fallback, summary)",
    )
    transport_ended_at: datetime | None = Field(
        default=None,
        description="when the alarm's transport ended (the alarm stays latched until a nurse "
        "acts on it)",
    )
    dispositions: list[DispositionOut] = Field(
        default_factory=list,
        description="the alarm distribution's reports from clinicians' devices, oldest first",
    )
    stored: bool = Field(
        default=True,
        description="false: pushed before it could be stored (storage stalled; a provisional "
        "negative id). The stored alarm with the same key replaces it once storage recovers",
    )

    @computed_field(
        description="robot/transport/kind: the identity a not-yet-stored alarm "
        "shares with the stored one that replaces it"
    )
    @property
    def key(self) -> str:
        return alarm_key(self.robot_id, self.transport_id, self.kind, self.ward)


class AlarmEventOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    alarm_id: int
    at: datetime
    actor: str
    action: str
    from_state: AlarmState | None
    to_state: AlarmState
    comment: str | None


class AcknowledgeIn(BaseModel):
    comment: str | None = Field(default=None, max_length=2000)


class ResolveIn(BaseModel):
    verdict: Verdict
    reason: FalseAlarmReason | None = Field(
        default=None, description="required when the verdict is false_alarm"
    )
    comment: str | None = Field(default=None, max_length=2000)

    @model_validator(mode="after")
    def _reason_matches_verdict(self) -> "ResolveIn":
        if self.verdict == Verdict.FALSE_ALARM and self.reason is None:
            raise ValueError("reason is required for a false_alarm verdict")
        if self.verdict != Verdict.FALSE_ALARM and self.reason is not None:
            raise ValueError("reason is only given for a false_alarm verdict")
        return self


def alarm_json(alarm) -> dict:
    """An alarm as the boards receive it (pushed after commit, and in the socket's snapshot)."""
    return AlarmOut.model_validate(alarm).model_dump(mode="json")
