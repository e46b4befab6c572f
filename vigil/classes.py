"""The three decision classes and the transport modes they are defined for."""

from enum import StrEnum


class Decision(StrEnum):
    NORMAL = "normal"
    EMERGENCY = "emergency"
    PAUSE = "pause"


class TransportMode(StrEnum):
    WALKING = "walking"
    WHEELCHAIR = "wheelchair"
    COMBINED = "combined"


#: Classes a model for each mode predicts, in the column order of its score vector.
MODE_CLASSES: dict[TransportMode, tuple[Decision, ...]] = {
    TransportMode.WALKING: (Decision.NORMAL, Decision.EMERGENCY),
    TransportMode.WHEELCHAIR: (Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE),
    TransportMode.COMBINED: (Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE),
}


class BehaviourState(StrEnum):
    """What the robot does with its decisions (robot_agent.behaviour drives it; the backend
    stores the last one each robot reported, protocol `behaviour_changed`)."""

    TRANSPORTING = "transporting"
    PAUSED = "paused"
    EMERGENCY_STOP = "emergency_stop"
    DETECTION_DEGRADED = "detection_degraded"
