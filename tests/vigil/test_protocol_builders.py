"""The wire's fast builders say exactly what the typed messages say: the ack, and a robot's
frames (the body its outbox stores, the body numbered, the batch of them)."""

from __future__ import annotations

import json

import pytest

from vigil.protocol import (
    MAX_FRAMES_PER_BATCH,
    Ack,
    FrameBatch,
    FrameRecord,
    ShadowDecision,
    ack_json,
    frame_batch_json,
    frame_body_json,
    frame_json,
    parse_robot_message,
    server_message_adapter,
)
from vigil.skeleton import N_FLOOR, N_KEYPOINTS


@pytest.mark.parametrize("seq", [0, 1, 41, 2**53])
def test_ack_json_is_the_ack_message(seq):
    assert ack_json(seq) == Ack(seq=seq).model_dump_json()
    assert server_message_adapter.validate_json(ack_json(seq)) == Ack(seq=seq)


KEYPOINTS = [[100.0 + i, 50.25, 0.9] for i in range(N_KEYPOINTS)]

FRAMES = {
    # only what a frame must have: every optional field left to its default
    "minimal": FrameRecord(seq=3, ts=1.5, keypoints=KEYPOINTS),
    # the optional fields given, as None or empty: the same frame as leaving them out
    "explicit-empty": FrameRecord(
        seq=0,
        ts=0.0,
        transport_id=None,
        keypoints=[[0.0, 0.0, 0.0]] * N_KEYPOINTS,
        depth=None,
        floor=None,
        decision=None,
        scores={},
        model_version=None,
        threshold=None,
        delay_ms=None,
        shadow=None,
    ),
    "classified": FrameRecord(
        seq=2**53,
        ts=1_733_430_000.123456,
        transport_id="robot-a-1733430000-1",
        keypoints=KEYPOINTS,
        depth=[2.5 if i % 3 else None for i in range(N_KEYPOINTS)],
        floor=[0.45, None, 1e-7][:N_FLOOR],
        decision="emergency",
        scores={"normal": 0.1, "pause": 0.2, "emergency": 0.7},
        model_version="upright-1",
        threshold=0.5,
        delay_ms=0,
    ),
    "shadow": FrameRecord(
        seq=17,
        ts=12.0,
        transport_id="t-1",
        keypoints=KEYPOINTS,
        decision="normal",
        scores={"normal": 1.0},
        model_version="upright-1",
        threshold=0.5,
        delay_ms=300,
        shadow=ShadowDecision(decision="pause", scores={}, model_version="candidate-2"),
    ),
    "unicode-and-escapes": FrameRecord(
        seq=5,
        ts=-0.0,
        transport_id='Station Ä-病棟-🚑 "north"\\\n',
        keypoints=KEYPOINTS,
        decision="pause",
        scores={"pause": 1.0},
        model_version="modèle-ü-2 ✓",
    ),
}


@pytest.fixture(params=list(FRAMES), ids=list(FRAMES))
def record(request) -> FrameRecord:
    return FRAMES[request.param]


def test_frame_body_is_the_record_without_its_seq(record):
    body = frame_body_json(record)
    assert body == record.model_dump_json(exclude={"seq"}, exclude_none=True)
    data = json.loads(body)
    assert "seq" not in data and {"ts", "keypoints"} <= set(data)
    assert None not in data.values()  # None is the default: left out


def test_numbered_body_is_the_records_json(record):
    text = frame_json(record.seq, frame_body_json(record))
    assert text == record.model_dump_json(exclude_none=True)
    assert FrameRecord.model_validate_json(text) == record
    assert FrameRecord.model_validate_json(text, strict=True) == record  # as the backend reads


@pytest.mark.parametrize("seq", [0, 1, 999, 2**53])
def test_a_body_numbered_again_is_the_record_with_that_seq(seq):
    """The outbox renumbers waiting frames after a welcome: the same body, another seq."""
    record = FRAMES["shadow"]
    text = frame_json(seq, frame_body_json(record))
    assert FrameRecord.model_validate_json(text) == record.model_copy(update={"seq": seq})
    assert json.loads(text)["seq"] == seq


@pytest.mark.parametrize("body", ["", "{}", "[1, 2]", "null", ' {"ts": 1}'])
def test_frame_json_refuses_what_is_not_a_frame_body(body):
    with pytest.raises(ValueError, match="frame body"):
        frame_json(1, body)


def test_frame_batch_is_the_batch_message():
    records = [record.model_copy(update={"seq": i}) for i, record in enumerate(FRAMES.values())]
    text = frame_batch_json([frame_json(r.seq, frame_body_json(r)) for r in records])
    batch = FrameBatch(frames=records)
    assert text == batch.model_dump_json(exclude_none=True)
    assert FrameBatch.model_validate_json(text) == batch
    assert parse_robot_message(text) == batch  # strict, as the backend's socket parses it


def test_frame_batch_of_one_and_of_the_most_the_backend_takes():
    record = FRAMES["minimal"]
    for count in (1, MAX_FRAMES_PER_BATCH):
        frames = [record.model_copy(update={"seq": i}) for i in range(count)]
        text = frame_batch_json([frame_json(f.seq, frame_body_json(f)) for f in frames])
        assert parse_robot_message(text) == FrameBatch(frames=frames)


@pytest.mark.parametrize("count", [0, MAX_FRAMES_PER_BATCH + 1])
def test_frame_batch_refuses_a_size_the_backend_refuses(count):
    body = frame_json(0, frame_body_json(FRAMES["minimal"]))
    with pytest.raises(ValueError, match="frame batch"):
        frame_batch_json([body] * count)
