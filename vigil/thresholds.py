"""Vectorised threshold sweeps: Youden's J (binary) and micro-F1 of Emergency (override rule)."""

from __future__ import annotations

import numpy as np

DEFAULT_GRID = np.linspace(0.0, 1.0, 1001)


def binary_counts(
    scores: np.ndarray, positive: np.ndarray, thresholds: np.ndarray = DEFAULT_GRID
) -> dict[str, np.ndarray]:
    """Confusion counts of `scores >= t` for every threshold t, by sorting (O((n + m) log n))."""
    scores = np.asarray(scores, np.float64)
    positive = np.asarray(positive, bool)
    pos, neg = np.sort(scores[positive]), np.sort(scores[~positive])
    tp = len(pos) - np.searchsorted(pos, thresholds, side="left")
    fp = len(neg) - np.searchsorted(neg, thresholds, side="left")
    return {"tp": tp, "fp": fp, "fn": len(pos) - tp, "tn": len(neg) - fp}


def youden_threshold(
    scores: np.ndarray, positive: np.ndarray, thresholds: np.ndarray = DEFAULT_GRID
) -> float:
    """Threshold maximising TPR - FPR (the first of equals, i.e. the lowest)."""
    c = binary_counts(scores, positive, thresholds)
    tpr = c["tp"] / max(c["tp"][0] + c["fn"][0], 1)
    fpr = c["fp"] / max(c["fp"][0] + c["tn"][0], 1)
    return float(thresholds[int(np.argmax(tpr - fpr))])


def f1_from_counts(tp, fp, fn) -> np.ndarray:
    tp, fp, fn = (np.asarray(a, np.float64) for a in (tp, fp, fn))
    denom = 2 * tp + fp + fn
    return np.divide(2 * tp, denom, out=np.zeros_like(denom), where=denom > 0)


def override_counts(
    scores: np.ndarray,
    positive: np.ndarray,
    emergency_index: int,
    thresholds: np.ndarray = DEFAULT_GRID,
) -> dict[str, np.ndarray]:
    """Counts for 'Emergency if p_E >= t, else arg-max' over all t (multiclass override rule)."""
    scores = np.asarray(scores, np.float64)
    positive = np.asarray(positive, bool)
    argmax_e = scores.argmax(axis=1) == emergency_index
    always = binary_counts(np.ones(argmax_e.sum()), positive[argmax_e], np.array([0.0]))
    rest = binary_counts(scores[~argmax_e, emergency_index], positive[~argmax_e], thresholds)
    tp, fp = rest["tp"] + always["tp"][0], rest["fp"] + always["fp"][0]
    n_pos = int(positive.sum())
    return {"tp": tp, "fp": fp, "fn": n_pos - tp, "tn": len(positive) - n_pos - fp}


def override_threshold(
    scores: np.ndarray,
    positive: np.ndarray,
    emergency_index: int,
    thresholds: np.ndarray = DEFAULT_GRID,
) -> float:
    """Threshold maximising F1 of the Emergency label under the override rule."""
    c = override_counts(scores, positive, emergency_index, thresholds)
    return float(thresholds[int(np.argmax(f1_from_counts(c["tp"], c["fp"], c["fn"])))])
