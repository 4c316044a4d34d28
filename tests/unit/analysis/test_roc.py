"""ROC and AUC (analysis.roc) against closed forms and an independent count.

* two equal-variance Gaussians, means 0 and d: AUC = Phi(d / sqrt 2) (the probability that an
  attack draw exceeds a benign one; Hanley & McNeil 1982, binormal model), within
  :data:`AUC_SIGMAS` standard errors of the Hanley-McNeil formula for the sample sizes;
* with ties: the trapezoid AUC is the Mann-Whitney statistic P(a > b) + P(a = b) / 2, counted
  here pair by pair;
* a threshold's operating point is a vertex of the curve (exactly).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from veriloc_rt.analysis.roc import (auc, detection_at_false_alarm, operating_point, roc_curve)

#: standard errors allowed between the sample AUC and the closed form (a 4-sigma band: the
#: test fails by chance with probability ~6e-5)
AUC_SIGMAS = 4.0
#: float summation of the trapezoids against the exact pair count
SUM_TOL = 1e-12


def _hanley_mcneil_se(a: float, n_attack: int, n_benign: int) -> float:
    """Standard error of the AUC (Hanley & McNeil 1982, Radiology 143, eq. 1)."""
    q1, q2 = a / (2.0 - a), 2.0 * a * a / (1.0 + a)
    var = (a * (1 - a) + (n_attack - 1) * (q1 - a * a) + (n_benign - 1) * (q2 - a * a)) / (
        n_attack * n_benign)
    return math.sqrt(var)


@pytest.mark.parametrize("d", [0.0, 0.5, 1.0, 2.0])
def test_two_gaussians_auc_matches_the_closed_form(d):
    rng = np.random.default_rng(11)
    n0, n1 = 3000, 2000
    benign, attack = rng.normal(0.0, 1.0, n0), rng.normal(d, 1.0, n1)
    want = float(norm.cdf(d / math.sqrt(2.0)))
    # a deviation statistic: large = attack-like, accepted iff stat <= t
    got = auc(roc_curve(benign, attack, "<="))
    assert abs(got - want) <= AUC_SIGMAS * _hanley_mcneil_se(want, n1, n0)
    # the same statistic negated, as a share accepted iff stat >= t: the same curve
    assert auc(roc_curve(-benign, -attack, ">=")) == pytest.approx(got, abs=SUM_TOL)


def test_auc_with_ties_is_the_mann_whitney_count():
    rng = np.random.default_rng(3)
    benign = rng.integers(0, 6, 400).astype(float)
    attack = np.concatenate([rng.integers(2, 9, 300).astype(float), [np.inf] * 20])
    diff = attack[:, None] - benign[None, :]
    want = float(((diff > 0).sum() + 0.5 * (diff == 0).sum()) / diff.size)
    c = roc_curve(benign, attack, "<=")
    assert auc(c) == pytest.approx(want, abs=SUM_TOL)
    # runs from accept-all (0, 0) to reject-all (1, 1), monotone
    assert (c.false_alarm[0], c.attack_reject[0]) == (0.0, 0.0)
    assert (c.false_alarm[-1], c.attack_reject[-1]) == (1.0, 1.0)
    assert np.all(np.diff(c.false_alarm) >= 0) and np.all(np.diff(c.attack_reject) >= 0)


@pytest.mark.parametrize("accept", ["<=", ">="])
def test_operating_point_is_a_vertex(accept):
    rng = np.random.default_rng(5)
    benign = np.round(rng.normal(0, 1, 200), 1)
    attack = np.round(rng.normal(1, 1, 150), 1)
    c = roc_curve(benign, attack, accept)
    vertices = set(zip(c.benign_accept.tolist(), c.attack_reject.tolist()))
    for t in (-5.0, -0.3, 0.0, 0.25, 1.0, 7.0, *benign[:5]):
        ba, ar = operating_point(benign, attack, float(t), accept)
        ok = benign <= t if accept == "<=" else benign >= t
        ko = attack <= t if accept == "<=" else attack >= t
        assert (ba, ar) == (ok.mean(), 1.0 - ko.mean())
        assert (ba, ar) in vertices


def test_detection_at_false_alarm_picks_the_best_allowed_vertex():
    # benign 0..9, attack 5..14 (deviation): threshold t rejects stats > t
    c = roc_curve(np.arange(10.0), np.arange(5.0, 15.0), "<=")
    t, fa, pd = detection_at_false_alarm(c, 0.2)
    # t = 7: benign 8, 9 rejected (P_FA 0.2), attack 8..14 rejected (P_D 0.7)
    assert (t, fa, pd) == (7.0, pytest.approx(0.2), pytest.approx(0.7))


def test_bad_statistics_are_refused():
    with pytest.raises(ValueError, match="NaN"):
        roc_curve([0.0, np.nan], [1.0], "<=")
    with pytest.raises(ValueError, match="-inf"):
        roc_curve([-np.inf], [1.0], "<=")
    with pytest.raises(ValueError, match="accept"):
        roc_curve([0.0], [1.0], "<")
