"""Outer folds of the nested cross-validation (worker.training.cross_validation.outer_folds)."""

from __future__ import annotations

import numpy as np

from worker.training.cross_validation import outer_folds
from worker.training.splits import grouped_folds


def test_train_only_sequences_are_trained_on_in_every_fold_and_never_held_out():
    is_positive = np.array([True] * 6 + [False] * 8 + [False] * 5)  # the last 5: hard negatives
    extra = np.arange(14, 19)
    folds = outer_folds(is_positive, 5, seed=3, train_only=extra)
    held_out = np.sort(np.concatenate([test for _, test in folds]))
    assert held_out.tolist() == list(range(14))  # each real sequence held out exactly once
    for train, test in folds:
        assert set(extra) <= set(train)
        assert not set(train) & set(test)
    # The real sequences are split exactly as without the extra ones.
    assert [test.tolist() for _, test in folds] == [
        test.tolist() for _, test in grouped_folds(is_positive[:14], 5, seed=3)
    ]
    assert [t.tolist() for _, t in outer_folds(is_positive[:14], 5, 3)] == [
        t.tolist() for _, t in grouped_folds(is_positive[:14], 5, 3)
    ]
