"""Where OTDOA multilateration stops giving trustworthy fixes: collinear BSs and biased RSTDs.

Independent references: GDOP in the TOA-with-clock-bias form (rows [u_i, 1], u_i the
horizontal part of the unit vector BS -> UE; a different formula from the library's RSTD form,
equal in value: standards-and-limits.md "Multilateration / GDOP"); the linearised parity
space of the whitened least squares for the residual a bias leaves; the triangle inequality
and the hyperbola asymptotes for 3 BSs. Boundaries found (2026-11):

* **near-collinear BSs** (BS 0 and 2 800 m apart, BS 1 offset h from their line, UE on the
  line): GDOP = 89.6 m / h for h <= 5 m (1/h law), GDOP = 10 at h = 8.96 m. The linearised
  GDOP predicts the Monte Carlo error (sigma = 1 m) at h = 100 m (1.59 m against 1.67 m); at
  h = 2 m the error saturates at 8.1 m instead of 44.8 m (the cross-track range differences
  become quadratic in the offset) and the solver reports ``no_convergence`` in 12 % of the
  fixes (a service failure, never NaN).
* **exactly collinear BSs**: both mirror images of the UE fit exactly; the solver returns one
  of them with ``ambiguous == False`` before the fix; both twins are now reported.
* **inconsistent RSTDs, 3 BSs** (triangle R = 289 m): zero redundancy; a bias b on one RSTD
  leaves a zero residual and moves the fix (36 m at b = 50 m, 387 m at 300 m). It is reported
  only (a) as ``diverged`` once the fix recedes past 10 km, just below the bias b_inf =
  396.5 m at which the hyperbolas meet at infinity, or (b) as ``residual_check_failed`` once
  the range difference exceeds the 500.6 m baseline (triangle inequality): b < -501 m, flagged
  once the residual passes 10 m (between -510 and -520 m).
* **inconsistent RSTDs, 4 BSs**: the rms residual grows as 0.28-0.45 m per m of bias; the
  10 m residual check trips at b = 22-35 m, the chi-square(1) test at sigma = 1 m and P_fa
  1e-3 at b = 4.8-7.8 m, both within 4 % of the linear parity-space prediction.
"""

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import chi2

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.phy.receiver.multilateration import Multilaterator, gdop

UE_H = 1.5
#: BS heights; the UE's is known to the solver
BS_H = 25.0
LINE_UE = np.array([60.0, 0.0, UE_H])


def _line_bs(h):
    return np.array([[-400.0, 0.0, BS_H], [0.0, h, BS_H], [400.0, 0.0, BS_H]])


def _rstd(bs, ue):
    d = np.linalg.norm(bs - ue, axis=1)
    return (d - d[0]) / SPEED_OF_LIGHT


def _gdop_clock_bias(bs, ue):
    """Horizontal GDOP of TOA positioning with an unknown clock bias: G = [u_i^T, 1]."""
    d = ue - bs
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    g = np.hstack([u[:, :2], np.ones((len(bs), 1))])
    p = np.linalg.inv(g.T @ g)
    return float(np.sqrt(p[0, 0] + p[1, 1]))


# -- collinear geometry ----------------------------------------------------------------------
def test_gdop_of_near_collinear_bs_grows_as_one_over_offset():
    hs = np.array([200.0, 100.0, 50.0, 20.0, 10.0, 5.0, 2.0, 1.0])
    g = np.array([gdop(_line_bs(h), LINE_UE) for h in hs])
    np.testing.assert_allclose(g, [_gdop_clock_bias(_line_bs(h), LINE_UE) for h in hs], rtol=1e-6)
    assert np.all(g[hs >= 50] < 2.5)                     # works: a usable geometry
    prod = (g * hs)[hs <= 5]
    np.testing.assert_allclose(prod, prod[-1], rtol=0.005)  # 1/h law near collinearity
    assert prod[-1] == pytest.approx(89.6, abs=0.5)
    h10 = brentq(lambda h: gdop(_line_bs(h), LINE_UE) - 10.0, 1.0, 50.0)
    assert 8.5 <= h10 <= 9.5                             # measured 8.96 m
    assert gdop(_line_bs(0.0), LINE_UE) == np.inf        # exactly collinear, UE on the line


def _monte_carlo(h, sigma_m, trials, seed):
    bs = _line_bs(h)
    d = np.linalg.norm(bs - LINE_UE, axis=1)
    rng = np.random.default_rng(seed)
    ml = Multilaterator(ue_height_m=UE_H)
    err, ok = [], []
    for _ in range(trials):
        toa = (d + sigma_m * rng.standard_normal(3)) / SPEED_OF_LIGHT
        res = ml(bs, toa - toa[0])
        assert np.all(np.isfinite(res.position))
        err.append(np.linalg.norm(res.position[:2] - LINE_UE[:2]))
        ok.append(res.ok)
    return np.sqrt(np.mean(np.square(err))), np.mean(ok)


def test_linearised_gdop_breaks_down_near_collinearity():
    sigma = 1.0
    rms, ok = _monte_carlo(100.0, sigma, 80, seed=1)
    assert ok == 1.0
    # rms of 80 trials: relative sd ~8 %
    assert rms / (sigma * gdop(_line_bs(100.0), LINE_UE)) == pytest.approx(1.0, abs=0.2)
    rms, ok = _monte_carlo(2.0, sigma, 60, seed=2)
    # the linear model predicts 44.8 m; the cross-track range differences are quadratic in
    # the offset there, so the error saturates near sqrt(2 sigma d) ~ 10 m
    assert rms / (sigma * gdop(_line_bs(2.0), LINE_UE)) < 0.3
    assert 4.0 < rms < 15.0
    # ... and some fixes become service failures (measured 12 %), never NaN
    assert 0.6 < ok < 0.97


@pytest.mark.parametrize("num_bs", [3, 4])
def test_exactly_collinear_bs_mirror_fix_is_flagged(num_bs):
    xs = [-400.0, 0.0, 400.0] if num_bs == 3 else [-400.0, -100.0, 150.0, 400.0]
    bs = np.array([[x, 0.0, BS_H] for x in xs])
    ue = np.array([60.0, 30.0, UE_H])
    res = Multilaterator(ue_height_m=UE_H)(bs, _rstd(bs, ue))
    near_truth = np.linalg.norm(res.position[:2] - ue[:2]) < 1.0
    # the mirror image (60, -30) fits exactly as well: it must be reported, not chosen
    # silently (was: ok, not ambiguous, 60 m off; fixed by mirrored starts about the BS line)
    assert near_truth or res.ambiguous or not res.ok
    mirror = ue[:2] * [1.0, -1.0]
    fixes = [res.position[:2]] + [a[:2] for a in res.alternatives]
    assert any(np.linalg.norm(f - ue[:2]) < 1.0 for f in fixes)
    assert any(np.linalg.norm(f - mirror) < 1.0 for f in fixes)


# -- inconsistent RSTDs ----------------------------------------------------------------------
TRIANGLE = np.array([[0.0, 289.0, BS_H], [-250.3, -144.5, BS_H], [250.3, -144.5, BS_H]])
UE = np.array([37.0, -21.0, UE_H])


def _biased(bs, i, bias_m, **cfg):
    rstd = _rstd(bs, UE)
    rstd[i] += bias_m / SPEED_OF_LIGHT
    return Multilaterator(ue_height_m=UE_H, **cfg)(bs, rstd)


def test_three_bs_absorb_a_bias_until_the_hyperbolas_stop_meeting():
    d = np.linalg.norm(TRIANGLE - UE, axis=1)
    r = d - d[0]
    # b_inf: the intersection is at infinity in direction w when r_i = -(s_i - s_0) . w with
    # |w| = 1 (far-field range differences), i.e. |A^-1 (r + b e_1)| = 1
    a = -(TRIANGLE[1:, :2] - TRIANGLE[0, :2])
    b_inf = brentq(lambda b: np.linalg.norm(np.linalg.solve(a, r[1:] + [b, 0.0])) - 1.0, 0.0, 600.0)
    assert b_inf == pytest.approx(396.5, abs=0.5)
    # works (undetectably): zero residual, the fix simply moves
    moved = []
    for b in (-450.0, -300.0, -100.0, 50.0, 300.0, b_inf - 10.0):
        res = _biased(TRIANGLE, 1, b)
        assert res.ok and res.residual_rms_m < 1e-6
        moved.append(np.linalg.norm(res.position[:2] - UE[:2]))
    assert moved[3] > 30.0 and moved[4] > 300.0          # 36 m and 387 m of undetected error
    # fails as a service failure when the fix recedes past max_distance_m (10 km)
    onset = brentq(lambda b: 0.5 - _biased(TRIANGLE, 1, b).ok, b_inf - 10.0, b_inf + 20.0, xtol=0.1)
    assert b_inf - 8.0 <= onset <= b_inf                 # measured 390-395 m
    res = _biased(TRIANGLE, 1, b_inf + 5.0)
    assert not res.ok and res.status == "diverged" and np.all(np.isfinite(res.position))
    # the other way the fix survives until the range difference exceeds the BS 0-1 baseline
    baseline = np.linalg.norm(TRIANGLE[1] - TRIANGLE[0])
    assert baseline == pytest.approx(500.6, abs=0.1)
    b_tri = -(baseline + r[1])
    assert _biased(TRIANGLE, 1, b_tri + 10.0).ok
    res = _biased(TRIANGLE, 1, b_tri - 25.0)
    assert not res.ok and res.status == "residual_check_failed"


SQUARE = np.vstack([TRIANGLE, [[0.0, -289.0, BS_H]]])


@pytest.mark.parametrize("i", [1, 2, 3])
def test_four_bs_residual_check_trips_where_the_parity_space_predicts(i):
    d = np.linalg.norm(SQUARE - UE, axis=1)
    u = (UE - SQUARE) / d[:, None]
    jac = (u[1:] - u[0])[:, :2]                          # d(d_i - d_0) / d(x, y)
    m = 3
    r_inv = np.eye(m) - np.ones((m, m)) / (m + 1)         # (I + 1 1^T)^-1
    proj = np.eye(m) - jac @ np.linalg.solve(jac.T @ r_inv @ jac, jac.T @ r_inv)
    e = np.zeros(m)
    e[i - 1] = 1.0
    res_unit = proj @ e                                   # raw residual per m of bias
    b_rms = 10.0 / (np.linalg.norm(res_unit) / np.sqrt(m))
    b_chi = np.sqrt(chi2.isf(1e-3, 1) / (res_unit @ r_inv @ res_unit))    # sigma = 1 m
    assert 20.0 < b_rms < 40.0 and 4.0 < b_chi < 9.0
    # both sides of each boundary, 5 % away
    assert _biased(SQUARE, i, 0.95 * b_rms).ok
    res = _biased(SQUARE, i, 1.05 * b_rms)
    assert not res.ok and res.status == "residual_check_failed"
    assert _biased(SQUARE, i, 0.98 * b_chi, sigma_m=1.0).ok
    res = _biased(SQUARE, i, 1.02 * b_chi, sigma_m=1.0)
    assert not res.ok and res.status == "residual_check_failed" and "chi-square" in res.reason
