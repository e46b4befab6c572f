"""Heartbeat's optional robot-health fields (protocol 1 extension) stay backward compatible."""

import pytest
from pydantic import ValidationError

from vigil.protocol import Heartbeat, parse_robot_message


def test_a_heartbeat_without_the_optional_fields_still_parses():
    message = parse_robot_message('{"type": "heartbeat", "ts": 1.5, "running_model": "m1"}')
    assert isinstance(message, Heartbeat)
    assert (message.outbox_frames, message.dropped_frames, message.model_error) == (None,) * 3


def test_robot_health_fields_round_trip():
    sent = Heartbeat(
        ts=2.0,
        running_model="m1",
        outbox_frames=12,
        dropped_frames=3,
        model_error="model m2 refused: sha256 of the downloaded file is ab",
    )
    assert parse_robot_message(sent.model_dump_json()) == sent


@pytest.mark.parametrize("field", ['"outbox_frames": -1', '"model_error": "' + "x" * 501 + '"'])
def test_bad_health_values_are_refused(field):
    with pytest.raises(ValidationError):
        parse_robot_message('{"type": "heartbeat", "ts": 1.0, ' + field + "}")
