"""GENERATED transports: PeTRA-like patient transports rendered as BODY_25 keypoints.

Everything this module produces is generated data (``GeneratedTransport.generated`` is always
True), meant for demos, load tests and the classes URFD lacks; never for claims about
detection quality.

A small kinematic body (pelvis position, trunk yaw/pitch/roll, hip, knee, shoulder and elbow
angles) is animated activity by activity, each activity carrying one fine label of
``vigil.taxonomy``, then projected through a Kinect-like pinhole camera on the robot
(640x480 pixels, 30 frames/s, depth along the optical axis in metres) with camera noise,
dropped keypoints, occlusion and 0-4 bystanders crossing the view. The same seed always
gives the same transport.

``GeneratedTransport.patient_sequence()`` gives the patient alone as plain arrays
(``GeneratedSequence``) and ``class_targets`` their class per frame in a mode.

The package, by concept: ``kinematics`` (the body and its parameters), ``camera`` (projection,
noise, occlusion), ``scripts`` (locomotion and the events of a transport), ``bystanders`` and
``transport`` (the assembly). Every public name is importable from ``vigil.synthetic``.
"""

from vigil.synthetic.bystanders import bystander_params
from vigil.synthetic.camera import (
    CAMERA_HEIGHT_M,
    CAMERA_MOUNT,
    CAMERA_TILT_RAD,
    FOCAL_PX,
    FPS,
    IMAGE_HEIGHT,
    IMAGE_WIDTH,
    MARKER_SIZE_M,
    MIN_VISIBLE_KEYPOINTS,
    CameraNoise,
    occlude,
    project,
    render,
)
from vigil.synthetic.kinematics import PARAMS, SIT_WHEELCHAIR, STAND, P, body_points, pose
from vigil.synthetic.scripts import (
    EMERGENCY_EVENTS,
    EVENTS,
    EVENTS_BY_LOCOMOTION,
    LABELS_BY_LOCOMOTION,
    Locomotion,
)
from vigil.synthetic.transport import (
    GeneratedSequence,
    GeneratedTransport,
    class_targets,
    generate_transport,
)

__all__ = [
    "CAMERA_HEIGHT_M",
    "CAMERA_MOUNT",
    "CAMERA_TILT_RAD",
    "EMERGENCY_EVENTS",
    "EVENTS",
    "EVENTS_BY_LOCOMOTION",
    "FOCAL_PX",
    "FPS",
    "IMAGE_HEIGHT",
    "IMAGE_WIDTH",
    "LABELS_BY_LOCOMOTION",
    "MARKER_SIZE_M",
    "MIN_VISIBLE_KEYPOINTS",
    "P",
    "PARAMS",
    "SIT_WHEELCHAIR",
    "STAND",
    "CameraNoise",
    "GeneratedSequence",
    "GeneratedTransport",
    "Locomotion",
    "body_points",
    "bystander_params",
    "class_targets",
    "generate_transport",
    "occlude",
    "pose",
    "project",
    "render",
]
