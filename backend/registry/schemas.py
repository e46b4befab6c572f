from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field

from backend.models.registry import DeploymentScope, DeploymentStatus, ModelStatus
from vigil.classes import BehaviourState, TransportMode
from vigil.inputs import InputName


class ModelSummary(BaseModel):
    model_config = ConfigDict(from_attributes=True, protected_namespaces=())

    id: int
    version: str
    mode: TransportMode
    kind: str
    status: ModelStatus
    sha256: str
    created_at: datetime
    job_id: int | None
    threshold: float
    delay_ms: int
    gold: dict | None = Field(description="headline gold-set figures")
    parent: str | None
    robots_assigned: int = 0
    robots_in_fleet: int = Field(default=0, description="robots registered, for 'on n of N'")
    canary_robot: str | None = Field(
        default=None, description="the robot running it as the canary of a live deployment"
    )
    inputs: list[InputName] = Field(description="what the model needs in every frame (manifest)")
    keypoints_only: bool = Field(description="needs keypoints only: can be a robot's fallback")


class ModelDetail(ModelSummary):
    manifest: dict
    metrics: dict
    lineage: dict
    plots: list[str]


class Comparison(BaseModel):
    a: ModelDetail
    b: ModelDetail
    rows: list[dict] = Field(description="metric, a, b, b - a, which is better")
    events: list[dict] = Field(description="per gold-set recording: result under a and under b")


ONLY_CAPABLE = (
    "ward or fleet: leave out the robots that cannot feed the model (listed in "
    "rollout.skipped) instead of refusing the promotion (409)"
)


class PromoteIn(BaseModel):
    scope: DeploymentScope
    target: str | None = Field(default=None, max_length=64, description="robot id or ward")
    canary_robot_id: str | None = Field(default=None, max_length=64)
    comment: str | None = Field(default=None, max_length=2000)
    only_capable: bool = Field(default=False, description=ONLY_CAPABLE)


class ShadowIn(BaseModel):
    scope: DeploymentScope
    target: str | None = Field(default=None, max_length=64)
    comment: str | None = Field(default=None, max_length=2000)
    only_capable: bool = Field(default=False, description=ONLY_CAPABLE)


class RollbackIn(BaseModel):
    reason: str = Field(default="rolled back by an engineer", max_length=2000)


class DeploymentOut(BaseModel):
    model_config = ConfigDict(from_attributes=True, protected_namespaces=())

    id: int
    model_version_id: int
    model_version: str = ""
    previous_model_version_id: int | None
    scope: DeploymentScope
    target: str | None
    shadow: bool
    status: DeploymentStatus
    gate_report: dict
    rollout: dict | None
    approved_by_id: int | None
    second_approver_id: int | None
    comment: str | None
    created_by_id: int | None
    created_at: datetime
    rolled_back_at: datetime | None
    rollback_reason: str | None
    alarms_judged: int = Field(default=0, description="alarms of this version with a verdict")
    alarms_rejected: int = Field(default=0, description="... of which nurses said false_alarm")


class FleetRobot(BaseModel):
    id: str
    name: str
    ward: str
    connected: bool
    target_version: str | None
    running_version: str | None
    running_sha256: str | None = Field(
        description="sha256 of the model file the robot says it runs (None: it did not say)"
    )
    shadow_version: str | None
    in_sync: bool = Field(
        description="it runs its target version, and that file's sha256 is the registry's"
    )
    agent_version: str | None
    last_seen_at: datetime | None
    inputs: list[InputName] = Field(
        description="what the robot can feed a model (its last hello; keypoints only if unsaid)"
    )
    inputs_reported: bool = Field(description="false: an older agent, or it never connected")
    fallback_version: str | None = Field(
        description="the keypoints-only model it keeps beside its target (None: not needed)"
    )
    target_feedable: bool = Field(description="it feeds every input its target model needs")
    detection_degraded: bool = Field(
        description="an unresolved detection_degraded alarm is open for it"
    )
    behaviour_state: BehaviourState | None = Field(
        default=None, description="what the robot last reported doing (None: never reported)"
    )
    behaviour_since: datetime | None = None
    behaviour_reason: str | None = None
    qualifies: bool | None = Field(
        default=None, description="with ?model_id=: it feeds every input that model needs"
    )
    missing_inputs: list[InputName] = Field(
        description="with ?model_id=: what it lacks for that model (else empty)"
    )
