"""The 95 % intervals of metrics.json (veriloc_rt/analysis/intervals.py) against independent
derivations: Clopper-Pearson from the beta quantiles and the binomial tail it inverts, the
vectorised bootstrap statistics against the ROC module on each resample, and the bootstrap's
coverage on a case with a known answer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import beta, binom, norm

from veriloc_rt.analysis.intervals import (binomial_ci, bootstrap_mean_ci, bootstrap_roc_ci,
                                         resampled_auc_pd)
from veriloc_rt.analysis.roc import auc, detection_at_false_alarm, roc_curve

#: scipy's beta quantiles and binomial tail agree with binomtest's root-finding to ~1e-12
#: relative; 1e-9 leaves room for its bracketing tolerance
QUANTILE_TOL = 1e-9


@pytest.mark.parametrize("k,n", [(0, 10), (1, 10), (7, 10), (10, 10), (73, 120), (1199, 1200)])
def test_clopper_pearson_is_the_beta_quantiles(k, n):
    lo, hi = binomial_ci(k, n)
    # Clopper & Pearson (1934): lo = B(0.025; k, n-k+1), hi = B(0.975; k+1, n-k), ends 0 and 1
    want_lo = 0.0 if k == 0 else beta.ppf(0.025, k, n - k + 1)
    want_hi = 1.0 if k == n else beta.ppf(0.975, k + 1, n - k)
    assert lo == pytest.approx(want_lo, rel=QUANTILE_TOL, abs=1e-15)
    assert hi == pytest.approx(want_hi, rel=QUANTILE_TOL, abs=1e-15)
    # ... the p at which seeing >= k (<= k) successes has probability 2.5 %
    if k > 0:
        assert binom.sf(k - 1, n, lo) == pytest.approx(0.025, rel=1e-7)
    if k < n:
        assert binom.cdf(k, n, hi) == pytest.approx(0.025, rel=1e-7)
    assert 0.0 <= lo <= k / n <= hi <= 1.0


def test_no_points_no_interval():
    assert binomial_ci(0, 0) is None


@pytest.mark.parametrize("accept", ["<=", ">="])
def test_resampled_statistics_equal_the_roc_of_each_resample(accept):
    rng = np.random.default_rng(5)
    # rounded to 0.1: many ties, which move the curve diagonally; a rule that rejects whatever
    # the threshold (inf on the rejecting side) on some attack points
    b = np.round(rng.normal(0.0, 1.0, 300), 1)
    a = np.round(rng.normal(0.8, 1.0, 150), 1)
    a[:10] = np.inf
    if accept == ">=":
        b, a = -b, -a
    ib = rng.integers(0, b.size, (25, b.size))
    ia = rng.integers(0, a.size, (25, a.size))
    aucs, pds = resampled_auc_pd(b, a, accept, 0.05, ib, ia)
    for r in range(25):
        c = roc_curve(b[ib[r]], a[ia[r]], accept)
        assert aucs[r] == pytest.approx(auc(c), abs=1e-12)   # sums in another order
        assert pds[r] == detection_at_false_alarm(c, 0.05)[2]


def test_bootstrap_covers_the_known_auc_and_detection_rate():
    """Benign N(0, 1), attack N(d, 1), valid iff stat <= t: AUC = Phi(d / sqrt 2), detection
    at false alarm 5 % = 1 - Phi(z_0.95 - d). Over many independent data sets the 95 %
    intervals must cover them about 95 % of the time."""
    d, nb, na, trials, alpha = 1.0, 400, 200, 200, 0.05
    true_auc = norm.cdf(d / math.sqrt(2.0))
    true_pd = 1.0 - norm.cdf(norm.ppf(1.0 - alpha) - d)
    rng = np.random.default_rng(11)
    hit_auc = hit_pd = 0
    for _ in range(trials):
        b, a = rng.normal(0.0, 1.0, nb), rng.normal(d, 1.0, na)
        (alo, ahi), (plo, phi) = bootstrap_roc_ci(b, a, "<=", alpha, rng, resamples=400)
        hit_auc += alo <= true_auc <= ahi
        hit_pd += plo <= true_pd <= phi
    # binomial tolerance: 3 sigma of a 95 % coverage over 200 trials (sigma 1.5 %), plus 2 %
    # for the percentile bootstrap's known undercoverage at these sizes (Efron & Tibshirani
    # 1993, Sec. 13.3) and the false-alarm constraint's downward step (a vertex at <= 5 %)
    sigma = math.sqrt(0.95 * 0.05 / trials)
    for hits in (hit_auc, hit_pd):
        assert 0.95 - 3 * sigma - 0.02 <= hits / trials <= 0.95 + 3 * sigma, (hit_auc, hit_pd)


def test_bootstrap_of_a_mean_is_the_normal_interval_for_many_values():
    """For 400 values the percentile bootstrap of the mean approaches mean -+ 1.96 s / sqrt n
    (s with ddof 0: the bootstrap's plug-in). Resampling noise of the 97.5 % percentile of
    1000 resamples: sqrt(0.025 x 0.975 / 1000) / phi(1.96) = 0.085 bootstrap sd = 4.3 % of the
    half-width (1.96 sd); the tolerance is 3 of those, 13 %."""
    x = np.random.default_rng(3).normal(0.7, 0.1, 400)
    lo, hi = bootstrap_mean_ci(list(x), np.random.default_rng(4))
    half = 1.959964 * x.std() / math.sqrt(x.size)
    assert lo == pytest.approx(x.mean() - half, abs=0.13 * half)
    assert hi == pytest.approx(x.mean() + half, abs=0.13 * half)
    assert bootstrap_mean_ci([None], np.random.default_rng(0)) is None
