"""Weighted N-anchor multilateration: the fix covariance against the closed-form GDOP geometry,
the chi-square integrity test's false-alarm rate on simulated Gaussian ToA noise, and fault
exclusion of a biased anchor."""

import numpy as np
import pytest
from scipy.stats import binom, chi2

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.phy.receiver.multilateration import Multilaterator, gdop

H_UE = 1.5


def anchors(n: int) -> np.ndarray:
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False) + 0.4
    r = 300.0 + 150.0 * (np.arange(n) % 3)
    return np.stack([r * np.cos(ang), r * np.sin(ang), np.full(n, 25.0)], -1)


def rstd_of(bs, ue, ref=0, toa_err_m=None):
    d = np.linalg.norm(bs - ue, axis=1) + (0.0 if toa_err_m is None else toa_err_m)
    return (d - d[ref]) / SPEED_OF_LIGHT


def covariance_closed_form(bs, ue, sig, ref=0):
    """(H^T C^-1 H)^-1: H rows (u_i - u_ref)[:2], u the unit vectors BS -> UE, C the RSTD
    covariance diag(sigma_i^2) + sigma_ref^2 1 1^T (written here from the definitions)."""
    u = (ue - bs) / np.linalg.norm(ue - bs, axis=1, keepdims=True)
    others = [i for i in range(len(bs)) if i != ref]
    h = (u[others] - u[ref])[:, :2]
    c = np.diag(sig[others] ** 2) + sig[ref] ** 2
    return np.linalg.inv(h.T @ np.linalg.inv(c) @ h)


def test_equal_weights_reproduce_gdop():
    bs, ue = anchors(7), np.array([40.0, -25.0, H_UE])
    sig = np.full(7, 2.0)
    res = Multilaterator(ue_height_m=H_UE)(bs, rstd_of(bs, ue), 0, range_std_m=sig)
    assert res.ok and np.linalg.norm(res.position - ue) < 1e-6
    # tr P = sigma^2 GDOP^2 (GDOP of TDOA with iid ToA noise, this module's gdop())
    assert np.trace(res.covariance) == pytest.approx(4.0 * gdop(bs, ue) ** 2, rel=1e-6)


def test_weighted_covariance_matches_closed_form_and_monte_carlo():
    bs, ue = anchors(8), np.array([-70.0, 55.0, H_UE])
    sig = np.array([1.0, 4.0, 2.0, 8.0, 1.5, 3.0, 6.0, 2.5])
    solver = Multilaterator(ue_height_m=H_UE, exclusion=False, false_alarm=1e-9)
    res = solver(bs, rstd_of(bs, ue), 0, range_std_m=sig)
    want = covariance_closed_form(bs, ue, sig)
    np.testing.assert_allclose(res.covariance, want, rtol=1e-4)
    # the spread of fixes under Gaussian ToA noise of those stds: 400 draws estimate each
    # variance within about 3 sqrt(2/400) = 21 % (chi-square spread of a sample variance)
    rng = np.random.default_rng(7)
    fixes = np.array([solver(bs, rstd_of(bs, ue, toa_err_m=rng.normal(0, sig)), 0,
                             range_std_m=sig).position[:2] for _ in range(400)])
    emp = np.cov(fixes.T)
    np.testing.assert_allclose(np.diag(emp), np.diag(want), rtol=0.21)


#: the test's size under test, and the binomial interval (two-sided 99.9 %) it must fall in
FALSE_ALARM = 0.05
TRIALS = 1500


def test_chi_square_false_alarm_rate_on_gaussian_residuals():
    bs, ue = anchors(8), np.array([25.0, 10.0, H_UE])
    sig = np.array([1.0, 2.0, 1.5, 3.0, 1.0, 2.5, 2.0, 1.2])
    solver = Multilaterator(ue_height_m=H_UE, exclusion=False, false_alarm=FALSE_ALARM)
    rng = np.random.default_rng(11)
    alarms = stats = 0
    values = []
    for _ in range(TRIALS):
        r = solver(bs, rstd_of(bs, ue, toa_err_m=rng.normal(0, sig)), 0, range_std_m=sig)
        alarms += not r.ok
        values.append(r.chi2)
    lo, hi = binom.ppf([0.0005, 0.9995], TRIALS, FALSE_ALARM)
    assert lo <= alarms <= hi, (alarms, lo, hi)
    # and the statistic is chi-square with N - 3 = 5 dof: its mean within 4 standard errors
    assert abs(np.mean(values) - 5.0) < 4 * np.sqrt(2 * 5.0 / TRIALS)
    assert chi2.sf(np.quantile(values, 0.5), 5) == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize("bad", [0, 3])
def test_biased_anchor_is_excluded(bad):
    bs, ue = anchors(9), np.array([60.0, -40.0, H_UE])
    sig = np.full(9, 2.0)
    rng = np.random.default_rng(bad)
    err = rng.normal(0, sig)
    err[bad] += 300.0      # a 1 us spoofed delay on one TRP (the reference for bad = 0)
    res = Multilaterator(ue_height_m=H_UE, false_alarm=1e-3)(bs, rstd_of(bs, ue, toa_err_m=err),
                                                             0, range_std_m=sig)
    assert res.ok and res.excluded == (bad,)
    assert bad not in res.used and len(res.used) == 8
    # within 4 sigma of the fix's own covariance
    assert np.linalg.norm(res.position[:2] - ue[:2]) < 4 * np.sqrt(np.trace(res.covariance))
    # without exclusion the test only flags it (the rms check left open, as the chain's
    # weighted fit has it)
    flagged = Multilaterator(ue_height_m=H_UE, false_alarm=1e-3, exclusion=False,
                             max_residual_m=1e9)(
        bs, rstd_of(bs, ue, toa_err_m=err), 0, range_std_m=sig)
    assert not flagged.ok and flagged.excluded == () and "chi-square" in flagged.reason
