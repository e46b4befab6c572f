"""assign_model's optional `stop_shadow` (protocol 1 extension) stays backward compatible: it is
on the wire only when true, and assignments without it still parse."""

import json

import pytest
from pydantic import ValidationError

from vigil.protocol import ModelAssignment, server_message_adapter

FIELDS = {
    "version": "m1",
    "url": "http://b/api/robot/models/m1/file",
    "sha256": "ab",
    "manifest": {},
}


def test_an_assignment_without_stop_shadow_parses_and_does_not_stop_the_shadow():
    message = server_message_adapter.validate_json(json.dumps({"type": "assign_model", **FIELDS}))
    assert isinstance(message, ModelAssignment)
    assert (message.shadow, message.stop_shadow) == (False, False)


def test_stop_shadow_is_sent_only_when_true():
    assert "stop_shadow" not in json.loads(ModelAssignment(**FIELDS).model_dump_json())
    assert "stop_shadow" not in json.loads(ModelAssignment(**FIELDS, shadow=True).model_dump_json())
    stop = ModelAssignment(**FIELDS, stop_shadow=True)
    assert json.loads(stop.model_dump_json())["stop_shadow"] is True
    assert server_message_adapter.validate_json(stop.model_dump_json()) == stop


def test_stop_shadow_on_a_shadow_assignment_is_refused():
    with pytest.raises(ValidationError, match="stop_shadow"):
        ModelAssignment(**FIELDS, shadow=True, stop_shadow=True)
