"""The real-backend fixtures of tests/backend and the small URFD model of the registry tests,
reused for the robot agent's tests."""

from tests.backend.conftest import ROBOT_TOKEN, robot, session_factory, settings  # noqa: F401
from tests.registry_fixtures import trained_model_dir  # noqa: F401
