"""The one permission table: which roles may call each route.

Every HTTP route of the API is listed here (a test walks the OpenAPI and fails on a route
missing from this table) and depends on `require(route_key)` which enforces it.
"""

from backend.models.users import Role

ANNOTATOR, NURSE, ENGINEER, ADMIN = Role.ANNOTATOR, Role.NURSE, Role.ENGINEER, Role.ADMIN
EVERYONE = frozenset(Role)
PUBLIC: frozenset[Role] = frozenset()  # no login needed
LABELLERS = frozenset({ANNOTATOR, ENGINEER, ADMIN})
ROBOT_TOKEN: frozenset[Role] = frozenset()  # no user login; the route checks the robot's token

#: (method, path template) -> roles allowed. PUBLIC routes need no credentials at all.
PERMISSIONS: dict[tuple[str, str], frozenset[Role]] = {
    ("POST", "/api/auth/login"): PUBLIC,
    ("POST", "/api/auth/logout"): EVERYONE,
    ("GET", "/api/auth/me"): EVERYONE,
    ("GET", "/api/health"): PUBLIC,
    ("GET", "/api/health/live"): PUBLIC,
    ("GET", "/api/health/ready"): PUBLIC,
    ("GET", "/api/users"): frozenset({ADMIN}),
    ("POST", "/api/users"): frozenset({ADMIN}),
    ("POST", "/api/users/{user_id}/deactivate"): frozenset({ADMIN}),
    ("POST", "/api/users/{user_id}/reactivate"): frozenset({ADMIN}),
    ("GET", "/api/robots"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("POST", "/api/robots"): frozenset({ADMIN}),
    ("GET", "/api/robots/{robot_id}"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("POST", "/api/robots/{robot_id}/token"): frozenset({ADMIN}),
    ("DELETE", "/api/robots/{robot_id}/token"): frozenset({ADMIN}),
    ("GET", "/api/transports"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/transports/{transport_id}"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/audit"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/alarms"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/alarms/{alarm_id}"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/alarms/{alarm_id}/events"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("POST", "/api/alarms/{alarm_id}/acknowledge"): frozenset({NURSE, ADMIN}),
    ("POST", "/api/alarms/{alarm_id}/resolve"): frozenset({NURSE, ADMIN}),
    ("GET", "/api/alarms/{alarm_id}/replay"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/alarm-history"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/alarm-fatigue"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/handover"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/handover.csv"): frozenset({NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/review-queue"): frozenset({ANNOTATOR, ENGINEER, ADMIN}),
    ("GET", "/api/videos"): frozenset({ANNOTATOR, ENGINEER, ADMIN}),
    ("GET", "/api/videos/{video_id}"): frozenset({ANNOTATOR, ENGINEER, ADMIN}),
    ("GET", "/api/videos/{video_id}/frames"): frozenset({ANNOTATOR, NURSE, ENGINEER, ADMIN}),
    ("GET", "/api/taxonomy"): EVERYONE,
    # Labelling workspace: annotators label, any annotator/engineer/admin may review another's
    # segments (never their own: checked in the service); only admins change a video's split.
    ("GET", "/api/labelling/videos"): LABELLERS,
    ("GET", "/api/labelling/facets"): LABELLERS,
    ("GET", "/api/labelling/videos/{video_id}"): LABELLERS,
    ("PATCH", "/api/labelling/videos/{video_id}"): frozenset({ADMIN}),
    ("GET", "/api/labelling/videos/{video_id}/segments"): LABELLERS,
    ("POST", "/api/labelling/videos/{video_id}/segments"): frozenset({ANNOTATOR, ADMIN}),
    ("PATCH", "/api/labelling/segments/{segment_id}"): frozenset({ANNOTATOR, ADMIN}),
    ("DELETE", "/api/labelling/segments/{segment_id}"): frozenset({ANNOTATOR, ADMIN}),
    ("POST", "/api/labelling/segments/{segment_id}/status"): frozenset({ANNOTATOR, ADMIN}),
    ("POST", "/api/labelling/videos/{video_id}/submit"): frozenset({ANNOTATOR, ADMIN}),
    ("POST", "/api/labelling/segments/{segment_id}/review"): LABELLERS,
    ("GET", "/api/labelling/segments/{segment_id}/history"): LABELLERS,
    ("GET", "/api/labelling/review-queue"): LABELLERS,
    ("GET", "/api/labelling/videos/{video_id}/export"): LABELLERS,
    ("POST", "/api/labelling/import"): frozenset({ANNOTATOR, ADMIN}),
    ("GET", "/api/labelling/videos/{video_id}/annotators"): LABELLERS,
    ("GET", "/api/labelling/videos/{video_id}/agreement"): LABELLERS,
    # Blurred pictures for everyone who handles recordings; ?blur=false: annotators only.
    ("GET", "/api/labelling/videos/{video_id}/rgb/{frame}"): frozenset(
        {ANNOTATOR, NURSE, ENGINEER, ADMIN}
    ),
    ("GET", "/api/labelling/videos/{video_id}/probability"): LABELLERS,
    ("POST", "/api/labelling/videos/{video_id}/view3d"): LABELLERS,
    ("GET", "/metrics"): frozenset({ENGINEER, ADMIN}),
    # Frame storage (issue 20): the admin's page; engineers choose archives as training data.
    ("GET", "/api/storage/summary"): frozenset({ADMIN}),
    ("POST", "/api/storage/retention"): frozenset({ADMIN}),
    ("GET", "/api/storage/archives"): frozenset({ENGINEER, ADMIN}),
    ("POST", "/api/storage/archives"): frozenset({ADMIN}),
    ("POST", "/api/storage/archives/{archive_id}/import"): frozenset({ENGINEER, ADMIN}),
    # Model registry, promotion, fleet and jobs (issue 8).
    ("GET", "/api/models"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/models/compare"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/models/{model_id}"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/models/{model_id}/plots/{name}"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/models/{model_id}/gate"): frozenset({ENGINEER, ADMIN}),
    ("POST", "/api/models/{model_id}/promote"): frozenset({ENGINEER}),
    ("POST", "/api/models/{model_id}/shadow"): frozenset({ENGINEER}),
    ("GET", "/api/deployments"): frozenset({ENGINEER, ADMIN}),
    ("POST", "/api/deployments/{deployment_id}/approve"): frozenset({ENGINEER}),
    ("POST", "/api/deployments/{deployment_id}/advance"): frozenset({ENGINEER}),
    ("POST", "/api/deployments/{deployment_id}/rollback"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/fleet"): frozenset({ENGINEER, ADMIN}),
    ("GET", "/api/jobs"): frozenset({ENGINEER, ADMIN}),
    ("POST", "/api/jobs"): frozenset({ENGINEER}),
    ("GET", "/api/jobs/{job_id}"): frozenset({ENGINEER, ADMIN}),
    ("POST", "/api/jobs/{job_id}/cancel"): frozenset({ENGINEER, ADMIN}),
    # Robots authenticate with their own token (X-Robot-Id + Bearer), checked in the route;
    # no user login applies, hence no user role.
    ("GET", "/api/robot/models/{version}/file"): ROBOT_TOKEN,
    ("GET", "/api/robot/models/{version}/manifest"): ROBOT_TOKEN,
}


def allowed(method: str, path: str, role: Role) -> bool:
    roles = PERMISSIONS[(method, path)]
    return not roles or role in roles
