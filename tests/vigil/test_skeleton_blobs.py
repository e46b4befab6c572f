"""decode_many: one decode for a recording's blobs gives what decoding each blob gives."""

from __future__ import annotations

import numpy as np
import pytest

from vigil.skeleton import (
    N_FLOOR,
    N_KEYPOINTS,
    decode_depth,
    decode_floor,
    decode_keypoints,
    decode_many,
    encode_depth,
    encode_floor,
    encode_keypoints,
)


def test_decode_many_matches_per_blob_decoding_with_nan_rows_for_none():
    rng = np.random.default_rng(3)
    keypoints = [
        encode_keypoints(rng.normal(300, 80, (25, 3)).astype(np.float32)) for _ in range(4)
    ]
    depth = [
        encode_depth(rng.uniform(1, 4, 25).astype(np.float32)),
        None,
        encode_depth(np.full(25, np.nan, np.float32)),
        None,
    ]
    floor = [None, encode_floor(rng.normal(size=3).astype(np.float32)), None, None]

    got = decode_many(keypoints, N_KEYPOINTS * 3).reshape(4, N_KEYPOINTS, 3)
    np.testing.assert_array_equal(got, np.stack([decode_keypoints(b) for b in keypoints]))
    got_depth = decode_many(depth, N_KEYPOINTS)
    expected_depth = [decode_depth(b) if b is not None else np.full(25, np.nan) for b in depth]
    np.testing.assert_array_equal(got_depth, np.stack(expected_depth))
    np.testing.assert_array_equal(
        decode_many(floor, N_FLOOR), np.stack([decode_floor(b) for b in floor])
    )
    assert got.dtype == np.float32 and decode_many([], N_FLOOR).shape == (0, N_FLOOR)


def test_decode_many_refuses_a_blob_of_the_wrong_length():
    good = encode_depth(np.ones(25, np.float32))
    with pytest.raises(ValueError, match="25 float32"):
        decode_many([good, good[:-4]], N_KEYPOINTS)
    with pytest.raises(ValueError, match="25 float32"):  # the right total, split wrongly
        decode_many([good + good[:4], good[4:]], N_KEYPOINTS)
