"""The equivalence harness's statistics (benchmarks/equivalence.py) against independent
derivations: simulated rejection rates, a textbook sample size, Holm's procedure by hand."""

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

PATH = Path(__file__).resolve().parents[3] / "benchmarks" / "equivalence.py"


@pytest.fixture(scope="module")
def eq():
    spec = importlib.util.spec_from_file_location("equivalence_harness", PATH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod   # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("p0,n", [(0.5, 2000), (0.9, 3000), (0.3, 5000)])
def test_power_matches_simulated_rejection_rate(eq, p0, n):
    """The stated power equals the rejection rate of the same z-test on simulated binomial
    samples at shares p0 and p0 + 0.01 (the pooled z statistic computed here, vectorised;
    |z| >= 1.959964 rejects at 0.05): 20,000 simulated pairs give a standard error <= 0.0036,
    tolerance 0.015 (4 standard errors plus the normal approximation's error at these n)."""
    rng = np.random.default_rng(7)
    reps = 20000
    k1 = rng.binomial(n, p0, reps)
    k2 = rng.binomial(n, p0 + 0.01, reps)
    pool = (k1 + k2) / (2 * n)
    z = (k2 - k1) / n / np.sqrt(pool * (1 - pool) * 2 / n)
    simulated = float(np.mean(np.abs(z) >= 1.959964))
    assert abs(eq.power_two_proportion(p0, n, n, 0.01, 0.05) - simulated) < 0.015


def test_sample_size_is_the_textbook_one(eq):
    """Fleiss (Statistical Methods for Rates and Proportions, 1981, the two-proportion sample
    size without continuity correction): p1 0.5, p2 0.51, alpha 0.05 two-sided, power 0.8 gives
    39,245 per group (computed here from the formula with z values 1.959964 and 0.841621)."""
    za, zb = 1.959964, 0.841621
    pbar = 0.505
    n = (za * math.sqrt(2 * pbar * (1 - pbar)) + zb * math.sqrt(0.5 * 0.5 + 0.51 * 0.49)) ** 2 / 0.01**2
    assert eq.n_for_power(0.5, 0.01, 0.05) == math.ceil(n)
    # and that n gives the power asked for, by the power function
    assert abs(eq.power_two_proportion(0.5, math.ceil(n), math.ceil(n), 0.01, 0.05) - 0.8) < 0.002


def test_two_proportion_p_is_the_z_test(eq):
    """30 of 100 against 45 of 100: pooled p 0.375, z = 0.15 / sqrt(0.375 0.625 0.02) = 2.1909,
    two-sided p = 0.02846 (normal table)."""
    assert eq.two_proportion_p(30, 100, 45, 100) == pytest.approx(0.02846, abs=5e-5)
    assert eq.two_proportion_p(0, 50, 0, 60) == 1.0


def test_wilson_interval(eq):
    """Wilson's interval of 8 of 10 at 95 %: [0.4902, 0.9433] (Newcombe, Stat. Med. 17, 1998,
    table I, as recalled: checked here against the closed form by hand)."""
    lo, hi = eq.wilson(8, 10)
    z = 1.959963984540054
    c = (0.8 + z * z / 20) / (1 + z * z / 10)
    h = z * math.sqrt(0.8 * 0.2 / 10 + z * z / 400) / (1 + z * z / 10)
    assert (lo, hi) == pytest.approx((c - h, c + h), abs=1e-12)
    assert (lo, hi) == pytest.approx((0.4902, 0.9433), abs=1e-4)


def test_holm_step_down(eq):
    """p = 0.001, 0.02, 0.03, 0.2 at 0.05: levels 0.0125, 0.0167, 0.025, 0.05; the first is
    rejected, the second not (0.02 > 0.0167), so neither are the later ones."""
    tests = [eq.Test("f", str(p), "", "", p) for p in (0.03, 0.001, 0.2, 0.02)]
    eq.holm(tests, 0.05)
    by = {t.name: t for t in tests}
    assert [by[k].rejected for k in ("0.001", "0.02", "0.03", "0.2")] == [True, False, False, False]
    assert by["0.02"].holm_alpha == pytest.approx(0.05 / 3)


def _sample(eq, rng, n_runs, n, shift=0.0, scale=1.0):
    s = eq.Sample()
    for _ in range(n_runs):
        out = rng.choice(np.array(eq_outcomes()), size=n, p=[0.8, 0.15, 0.05])
        s.add(("none", "standard"), s.outcomes, list(out))
        s.add("none", s.errors, list(rng.exponential(scale + shift, n)))
        s.add(("none", "ABSA"), s.rejects, [list(rng.random(n) < 0.05)])
        s.add(("none", "ABSA"), s.stats, [list(rng.gamma(2.0, 2.0, n))])
        snr = rng.uniform(-10, 20, 3 * n)
        s.links += [(x, True, rng.normal(shift, scale)) for x in snr]
        s.points += n
    return s


def eq_outcomes():
    return ("success", "large_error", "service_failure")


def test_compare_same_distribution_is_not_distinguished(eq):
    """Two samples of one distribution: no test rejects at the Holm family level (the chance
    that one does is at most 5 %; with this fixed seed it does not)."""
    rng = np.random.default_rng(11)
    tests = eq.compare(_sample(eq, rng, 4, 300), _sample(eq, rng, 4, 300))
    assert tests and not any(t.rejected for t in tests)


def test_compare_sees_a_shift(eq):
    """ToA errors shifted by 0.3 sigma and position errors' mean 1.3x, 1200 points a version
    (3600 links): the KS tests reject (their power at these sizes is ~1: the KS statistic's
    5 % critical value is 1.36 sqrt(2 / 1200) = 0.056, the CDFs differ by up to 0.12 and 0.10)."""
    rng = np.random.default_rng(12)
    tests = eq.compare(_sample(eq, rng, 4, 300), _sample(eq, rng, 4, 300, shift=0.3))
    rejected = {t.family for t in tests if t.rejected}
    assert "ToA per SNR bin" in rejected and "position error" in rejected
