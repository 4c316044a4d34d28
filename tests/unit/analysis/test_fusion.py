"""Fused decisions (analysis.fusion): k-of-n voting against a hand-written truth table, the
Neyman-Pearson threshold against hand-counted scores, and the fused test's false-alarm rate on
synthetic data against its target."""

from __future__ import annotations

import math

import numpy as np
import pytest

from veriloc_rt.analysis.fusion import NaiveBayesLR, kofn_votes, np_threshold, split_by_index
from veriloc_rt.analysis.roc import auc, roc_curve

#: binomial standard deviations allowed between the achieved and the target false-alarm rate
#: (the threshold's own estimate on the training points and the test share both count)
FA_SIGMAS = 4.0

# three detectors (1 valid, 0 reject) -> rejected by 1-of-3, 2-of-3 (majority), 3-of-3,
# worked by hand
TRUTH = [
    ((1, 1, 1), (False, False, False)),
    ((0, 1, 1), (True, False, False)),
    ((1, 0, 1), (True, False, False)),
    ((1, 1, 0), (True, False, False)),
    ((0, 0, 1), (True, True, False)),
    ((0, 1, 0), (True, True, False)),
    ((1, 0, 0), (True, True, False)),
    ((0, 0, 0), (True, True, True)),
]


def test_k_of_n_against_the_truth_table():
    valid = np.array([v for v, _ in TRUTH], dtype=bool)
    votes = kofn_votes(valid)
    for k in (1, 2, 3):
        rejected = ~(votes <= k - 1)   # the fused statistic's rule: valid iff votes <= k - 1
        assert rejected.tolist() == [r[k - 1] for _, r in TRUTH]


def test_np_threshold_counts_the_scores_above():
    scores = np.arange(1.0, 101.0)       # 1..100
    assert np_threshold(scores, 0.05) == 95.0   # 96..100 above: 5 of 100
    assert np_threshold(scores, 0.049) == 96.0  # 4 of 100
    tied = np.array([0.0] * 90 + [1.0] * 10)
    assert np_threshold(tied, 0.05) == 1.0      # 0.0 would leave 10 % above


def test_split_keeps_blocks_together_and_deals_them_evenly():
    part = split_by_index(95, np.random.default_rng(1), 10)
    blocks = [part[i:i + 10] for i in range(0, 95, 10)]      # the last block holds 5
    assert all(len(set(b.tolist())) == 1 for b in blocks)
    # 10 blocks dealt to 3 parts in turn: 4, 3, 3 blocks
    assert sorted(np.bincount([b[0] for b in blocks], minlength=3).tolist()) == [3, 3, 4]


def test_np_fusion_false_alarm_meets_the_target():
    rng = np.random.default_rng(7)
    alpha, n_train, n_test = 0.05, 6000, 6000

    def draw(n, attack):
        x = rng.normal(0.0, 1.0, (n, 3))
        if attack:
            x += np.array([1.0, 0.5, 0.0])
        x[:, 2] = np.abs(x[:, 2])
        x[rng.random(n) < (0.3 if attack else 0.02), 2] = np.inf   # a rule that always rejects
        return x

    model = NaiveBayesLR(draw(n_train, False), draw(n_train, True))
    tau = np_threshold(model.score(draw(n_train, False)), alpha)
    b_test, a_test = model.score(draw(n_test, False)), model.score(draw(n_test, True))
    fa = float((b_test > tau).mean())
    sigma = math.sqrt(alpha * (1 - alpha) * (1 / n_train + 1 / n_test))
    assert abs(fa - alpha) <= FA_SIGMAS * sigma
    # and it uses the features: better than the best single one (AUC of feature 0 alone:
    # Phi(1/sqrt 2) = 0.760)
    assert auc(roc_curve(b_test, a_test, "<=")) > 0.80


def test_naive_bayes_refuses_bad_input():
    with pytest.raises(ValueError, match="num_stats"):
        NaiveBayesLR(np.zeros((3, 2)), np.zeros((3, 1)))
    with pytest.raises(ValueError, match="NaN"):
        NaiveBayesLR(np.full((3, 1), np.nan), np.zeros((3, 1)))
