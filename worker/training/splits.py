"""Folds of whole sequences (never a sequence in two folds), stratified by sequence kind."""

from __future__ import annotations

import numpy as np


def grouped_folds(
    is_positive_sequence: np.ndarray, n_splits: int = 5, seed: int = 0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(train, test) arrays of sequence indices; positives and negatives spread evenly."""
    is_positive_sequence = np.asarray(is_positive_sequence, bool)
    if n_splits < 2:
        raise ValueError("n_splits must be at least 2")
    rng = np.random.default_rng(seed)
    fold_of = np.empty(len(is_positive_sequence), np.int64)
    for kind in (True, False):
        members = rng.permutation(np.flatnonzero(is_positive_sequence == kind))
        fold_of[members] = np.arange(len(members)) % n_splits
    everything = np.arange(len(is_positive_sequence))
    return [(everything[fold_of != k], everything[fold_of == k]) for k in range(n_splits)]
