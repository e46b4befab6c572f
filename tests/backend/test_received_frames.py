"""A validated frame batch compacted for the writer stores exactly what the frame said."""

from __future__ import annotations

import json

import numpy as np
import pytest

from backend.ingest.bulk import FRAME_COLUMNS
from backend.ingest.received import ROW_TAIL_START, ReceivedFrame, compact, scores_json
from vigil.classes import Decision
from vigil.protocol import FrameRecord, ShadowDecision
from vigil.skeleton import (
    decode_depth,
    decode_keypoints,
    encode_depth,
    encode_floor,
    encode_keypoints,
)


def record(**changes) -> FrameRecord:
    fields = {
        "seq": 7,
        "ts": 1_700_000_000.25,
        "transport_id": "t-1",
        "keypoints": [[100.5 + i, -3.25 * i, 0.9] for i in range(25)],
        "depth": [1.5 + i / 10 for i in range(23)] + [None, None],
        "decision": "emergency",
        "scores": {"normal": 0.1, "emergency": 0.9},
        "model_version": "m-1",
        "threshold": 0.4,
        "delay_ms": 120,
    }
    return FrameRecord(**(fields | changes))


def test_row_tail_lines_up_with_the_frame_columns():
    assert ReceivedFrame._fields[ROW_TAIL_START:] == FRAME_COLUMNS[5:]


def test_blobs_are_the_canonical_skeleton_encoding():
    frame = record()
    stored = compact(frame)
    assert stored.keypoints == encode_keypoints(np.array(frame.keypoints))
    np.testing.assert_array_equal(
        decode_keypoints(stored.keypoints), np.array(frame.keypoints, np.float32)
    )
    depth = np.array([np.nan if v is None else v for v in frame.depth], np.float32)
    assert stored.depth == encode_depth(depth)
    assert np.isnan(decode_depth(stored.depth)[-2:]).all()
    with_floor = compact(record(floor=[1.25, 0.5, None]))
    assert with_floor.floor == encode_floor(np.array([1.25, 0.5, np.nan], np.float32))
    assert compact(record(floor=[None, None, None])).floor is None


def test_scalars_and_decisions_are_kept_as_sent():
    frame = record(
        shadow=ShadowDecision(decision="pause", scores={"pause": 0.7}, model_version="m-2")
    )
    stored = compact(frame)
    assert (stored.seq, stored.ts, stored.transport_id) == (7, 1_700_000_000.25, "t-1")
    assert (stored.model_version, stored.threshold, stored.delay_ms) == ("m-1", 0.4, 120)
    assert stored.decision == "emergency" and type(stored.decision) is str
    assert (stored.shadow_decision, stored.shadow_model_version) == ("pause", "m-2")
    assert json.loads(stored.shadow_scores) == {"pause": 0.7}


def test_optional_parts_missing():
    stored = compact(record(depth=None, decision=None, scores={}, threshold=None))
    assert stored.depth is None and stored.floor is None
    assert stored.decision is None and stored.scores is None and stored.threshold is None
    assert stored.shadow_decision is stored.shadow_scores is stored.shadow_model_version is None


@pytest.mark.parametrize(
    "scores",
    [
        {"normal": 0.1, "emergency": 0.9},
        {"emergency": 1, "pause": 0},
        {"normal": 1e-7, "pause": -2.5e300, "emergency": 0.30000000000000004},
    ],
)
def test_scores_text_is_what_json_dumps_gives(scores):
    validated = record(scores=scores).scores
    assert scores_json(validated) == json.dumps({str(k): v for k, v in validated.items()})
    assert json.loads(scores_json(validated)) == {Decision(k).value: v for k, v in scores.items()}
