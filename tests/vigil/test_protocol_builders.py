"""The wire's fast builders say exactly what the typed messages say."""

from __future__ import annotations

import pytest

from vigil.protocol import Ack, ack_json, server_message_adapter


@pytest.mark.parametrize("seq", [0, 1, 41, 2**53])
def test_ack_json_is_the_ack_message(seq):
    assert ack_json(seq) == Ack(seq=seq).model_dump_json()
    assert server_message_adapter.validate_json(ack_json(seq)) == Ack(seq=seq)
