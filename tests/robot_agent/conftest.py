"""The real-backend fixtures of tests/backend, reused for the robot agent's loopback tests."""

from tests.backend.conftest import ROBOT_TOKEN, robot, session_factory, settings  # noqa: F401
