import time

import numpy as np
import pytest

from vigil.classes import Decision
from vigil.policy import DecisionPolicy, alarm_mask, apply_delay, raw_decisions
from vigil.thresholds import binary_counts, override_threshold, youden_threshold

N, E, P = Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE
THREE = (N, E, P)


def test_override_rule_emergency_wins_at_threshold_else_argmax():
    scores = np.array(
        [
            [0.55, 0.25, 0.20],  # E below t -> argmax Normal
            [0.35, 0.30, 0.35],  # E at t -> Emergency although not the largest
            [0.10, 0.20, 0.70],  # Pause wins by argmax
            [0.20, 0.60, 0.20],
        ]
    )
    assert raw_decisions(scores, THREE, 0.3).tolist() == [0, 1, 2, 1]
    assert raw_decisions(scores, THREE, 0.31).tolist() == [0, 0, 2, 1]


def test_override_threshold_maximises_emergency_f1_on_crafted_scores():
    # Emergencies have p_E around 0.35 but never the arg-max; normals with p_E 0.2 or 0.4.
    scores = np.array([[0.6, 0.35, 0.05]] * 8 + [[0.5, 0.2, 0.3]] * 10 + [[0.55, 0.4, 0.05]] * 1)
    positive = np.array([True] * 8 + [False] * 11)
    t = override_threshold(scores, positive, emergency_index=1)
    assert 0.2 < t <= 0.35
    pred = raw_decisions(scores, THREE, t) == 1
    assert pred[:8].all() and pred[8:18].sum() == 0


def test_youden_threshold_on_crafted_scores():
    scores = np.array([0.1, 0.2, 0.3, 0.45, 0.6, 0.7, 0.8, 0.9])
    positive = np.array([0, 0, 0, 0, 1, 1, 1, 1], bool)
    t = youden_threshold(scores, positive)
    assert 0.45 < t <= 0.6
    # one positive hidden among negatives: J is still maximal between 0.45 and 0.6
    positive2 = np.array([0, 0, 1, 0, 1, 1, 1, 1], bool)
    t2 = youden_threshold(scores, positive2)
    assert 0.45 < t2 <= 0.6


def test_threshold_sweep_is_vectorised_and_fast():
    rng = np.random.default_rng(0)
    scores, positive = rng.random(20_000), rng.random(20_000) < 0.2
    thresholds = np.linspace(0, 1, 1000)
    start = time.perf_counter()
    counts = binary_counts(scores, positive, thresholds)
    elapsed = time.perf_counter() - start
    k = 437
    assert counts["tp"][k] == np.sum((scores >= thresholds[k]) & positive)
    assert counts["fp"][k] == np.sum((scores >= thresholds[k]) & ~positive)
    assert elapsed < 0.5  # milliseconds in practice; generous bound for a loaded machine


def _stream(raw, dt=0.1):
    return np.array(raw), np.arange(len(raw)) * dt


def test_delay_filter_raises_only_after_the_change_held():
    raw, t = _stream([0, 1, 1, 1, 0, 1, 1, 1, 1, 1])
    out = apply_delay(raw, t, delay_s=0.3)
    # first run lasts 0.2 s (< 0.3): suppressed; second run raised at its 4th frame (0.3 s)
    assert out.tolist() == [0, 0, 0, 0, 0, 0, 0, 0, 1, 1]
    assert np.flatnonzero(alarm_mask(out, 1)).tolist() == [8]
    assert apply_delay(raw, t, 0.0).tolist() == raw.tolist()


def test_delay_filter_holds_previous_decision_while_pending_and_normal_is_immediate():
    raw, t = _stream([1, 1, 2, 2, 2, 0, 0])
    out = apply_delay(raw, t, delay_s=0.1)
    assert out.tolist() == [0, 1, 1, 2, 2, 0, 0]


def test_streaming_policy_equals_batch_filter_and_reports_pending():
    rng = np.random.default_rng(3)
    scores = rng.dirichlet([1, 1, 1], size=300)
    t = np.cumsum(rng.uniform(0.02, 0.06, size=300))
    policy = DecisionPolicy(THREE, threshold=0.45, delay_s=0.12)
    streamed, pending = [], []
    for s, ts in zip(scores, t, strict=True):
        streamed.append(THREE.index(policy.update(s, ts)))
        pending.append(policy.pending)
    raw = raw_decisions(scores, THREE, 0.45)
    batch = apply_delay(raw, t, 0.12)
    assert streamed == batch.tolist()
    assert any(pending)
    assert np.array_equal(np.array(pending), raw != batch)
    policy.reset()
    assert policy.decision == N and not policy.pending


def test_policy_validates_inputs():
    with pytest.raises(ValueError, match="threshold"):
        DecisionPolicy((N, E), 1.5, 0)
    with pytest.raises(ValueError, match="scores"):
        DecisionPolicy((N, E), 0.5, 0).update(np.array([0.1, 0.2, 0.7]), 0.0)
