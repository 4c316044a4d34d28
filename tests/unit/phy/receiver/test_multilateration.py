"""OTDOA multilateration and GDOP.

GDOP references: /work/shared/reference/standards-and-limits.md section 2 ("Multilateration /
GDOP", V-calc), 3-gNB triangle and 6-gNB hexagon of circumradius 500 m, 2-D. The reference table
does not state the offset directions; they were identified here as along +y with the triangle's
vertex at 90 deg and the hexagon's at 0 deg, except the triangle's 400 m entry (towards the
opposite edge, -y). Values rounded to 3-4 significant digits.
"""

import numpy as np
import pytest
from scipy import stats

from veriloc_rt.constants import SPEED_OF_LIGHT as C
from veriloc_rt.phy.receiver.multilateration import (STATUS_DIVERGED, STATUS_NO_CONVERGENCE,
                                                     STATUS_OK, STATUS_RESIDUAL, STATUS_TOO_FEW,
                                                     Multilaterator, chan_initialisation, gdop,
                                                     multilaterate)

#: exact RSTDs: LM stops at xtol 1e-12, so anything above float noise is a bug; brief asks sub-mm
TOL_EXACT_M = 1e-3
#: GDOP table is rounded to 3-4 significant digits
TOL_GDOP_REL = 2.5e-3


def _polygon(n, radius, first_deg, height=None):
    a = np.radians(first_deg + 360.0 / n * np.arange(n))
    pts = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=-1)
    return pts if height is None else np.hstack([pts, np.full((n, 1), height)])


def _rstd(bs, ue):
    d = np.linalg.norm(bs - ue, axis=1)
    return (d - d[0]) / C


@pytest.mark.parametrize("ue_xy, expect", [
    ((0, 0), 1.155), ((0, 250), 1.286), ((0, -400), 1.969), ((0, 1000), 22.3), ((0, 3000), 140),
])
def test_gdop_triangle_reference_table(ue_xy, expect):
    assert gdop(_polygon(3, 500.0, 90.0), np.array(ue_xy, float)) == pytest.approx(
        expect, rel=TOL_GDOP_REL)


@pytest.mark.parametrize("ue_xy, expect", [
    ((0, 0), 0.816), ((0, 250), 0.854), ((0, 400), 1.050), ((0, 1000), 10.6), ((0, 3000), 85.9),
])
def test_gdop_hexagon_reference_table(ue_xy, expect):
    assert gdop(_polygon(6, 500.0, 0.0), np.array(ue_xy, float)) == pytest.approx(
        expect, rel=TOL_GDOP_REL)


def test_gdop_centre_closed_form_and_reference_independence():
    # centre of a regular N-gon: H^T R^-1 H = (N/2) I_2 -> GDOP = 2 / sqrt(N)
    for n in (3, 4, 6, 8):
        bs = _polygon(n, 700.0, 17.0)
        for ref in range(n):
            assert gdop(bs, np.zeros(2), ref_index=ref) == pytest.approx(2 / np.sqrt(n), rel=1e-12)
    assert gdop(_polygon(2, 500.0, 0.0), np.zeros(2)) == np.inf
    collinear = np.array([[0.0, 0.0], [100.0, 0.0], [200.0, 0.0]])
    assert gdop(collinear, np.array([50.0, 0.0])) == np.inf


@pytest.mark.parametrize("n_bs, half_width_m", [(3, 140.0), (4, 600.0), (6, 600.0)])
def test_exact_rstds_recover_position_sub_mm(n_bs, half_width_m):
    # 3 BSs: inside the triangle (inradius 144.5 m) the fix is unique; outside see below
    bs = _polygon(n_bs, 289.0, 90.0, height=25.0)
    rng = np.random.default_rng(n_bs)
    for _ in range(30):
        ue = np.append(rng.uniform(-half_width_m, half_width_m, 2), 1.5)
        if n_bs == 3 and np.linalg.norm(ue[:2]) > 144.0:
            continue
        res = multilaterate(bs, _rstd(bs, ue))
        assert res.ok and res.status == STATUS_OK and res.reason == ""
        assert np.linalg.norm(res.position - ue) < TOL_EXACT_M
        assert res.residual_rms_m < 1e-6 and res.num_bs == n_bs and res.dof == n_bs - 3


def test_three_bs_outside_hull_two_exact_fixes_are_both_reported():
    """Two hyperbolas can cross twice: with 3 BSs and the UE outside their hull both crossings
    fit the RSTDs exactly; the result keeps the one nearest the centroid and lists the other."""
    bs = _polygon(3, 289.0, 90.0, height=25.0)
    ue = np.array([445.36697975, -269.55074766, 1.5])
    res = multilaterate(bs, _rstd(bs, ue))
    assert res.ok and res.ambiguous
    fixes = [res.position] + res.alternatives
    assert min(np.linalg.norm(f - ue) for f in fixes) < TOL_EXACT_M
    for f in fixes:                         # every listed fix reproduces the RSTDs
        np.testing.assert_allclose(_rstd(bs, f), _rstd(bs, ue), atol=1e-12)


def test_chan_closed_form_contains_exact_solution():
    bs = _polygon(3, 289.0, 90.0, height=25.0)
    ue = np.array([120.0, -40.0, 1.5])
    cands = chan_initialisation(bs, _rstd(bs, ue) * C, 0, 1.5)
    assert min(np.linalg.norm(c - ue[:2]) for c in cands) < 1e-6


def test_other_reference_index_and_valid_mask():
    bs = _polygon(5, 289.0, 0.0, height=25.0)
    ue = np.array([30.0, 60.0, 1.5])
    d = np.linalg.norm(bs - ue, axis=1)
    rstd = (d - d[2]) / C
    res = multilaterate(bs, rstd, ref_index=2, valid=[True, False, True, True, False])
    assert res.ok and res.num_bs == 3 and np.linalg.norm(res.position - ue) < TOL_EXACT_M


def test_noisy_rstds_error_matches_gdop_and_chi2_is_chi2():
    """iid ToA noise sigma = 1 m: the rms horizontal error must be GDOP * sigma (first order) and
    the whitened SSR / sigma^2 must follow chi2(N - 3)."""
    bs = _polygon(6, 500.0, 0.0, height=25.0)
    ue = np.array([80.0, 120.0, 1.5])
    d = np.linalg.norm(bs - ue, axis=1)
    solver = Multilaterator(sigma_m=1.0, false_alarm=1e-9)
    rng = np.random.default_rng(11)
    err2, chis = [], []
    for _ in range(300):
        toa = d + rng.standard_normal(6)
        res = solver(bs, (toa - toa[0]) / C)
        assert res.ok
        err2.append(np.sum((res.position - ue) ** 2))
        chis.append(res.chi2)
    rmse = np.sqrt(np.mean(err2))
    # 300 trials: the rms of a chi-like(2) error has ~3 % relative sd; 15 % band is > 4 sd
    assert rmse == pytest.approx(gdop(bs, ue), rel=0.15)
    assert stats.kstest(chis, "chi2", args=(3,)).statistic < 1.949 / np.sqrt(300)


def test_three_bs_non_intersecting_hyperbolas_fail_without_nan():
    # |d_1 - d_0| can never exceed the baseline |b_1 - b_0| = 500.6 m: no solution exists
    bs = _polygon(3, 289.0, 90.0, height=25.0)
    rstd = np.array([0.0, 700.0 / C, 10.0 / C])
    res = multilaterate(bs, rstd)
    assert not res.ok and res.service_failure
    assert res.status in (STATUS_RESIDUAL, STATUS_DIVERGED, STATUS_NO_CONVERGENCE) and res.reason
    assert np.all(np.isfinite(res.position))


def test_biased_rstd_with_redundancy_is_caught_by_residual_check():
    bs = _polygon(4, 289.0, 45.0, height=25.0)
    ue = np.array([50.0, -20.0, 1.5])
    rstd = _rstd(bs, ue)
    rstd[2] += 200.0 / C                  # a spoofed/NLoS 200 m bias on one BS
    res = multilaterate(bs, rstd)
    assert not res.ok and res.status == STATUS_RESIDUAL and "residual" in res.reason
    res = multilaterate(bs, rstd, sigma_m=1.0, max_residual_m=1e4)
    assert not res.ok and res.status == STATUS_RESIDUAL and "chi-square" in res.reason


@pytest.mark.parametrize("rstd, valid, word", [
    ([0.0, 1e-7], None, "2 BSs"),
    ([0.0, np.nan, 1e-7], None, "2 BSs"),
    ([0.0, 1e-7, 2e-7], [False, True, True], "reference"),
])
def test_too_few_bs_is_a_service_failure(rstd, valid, word):
    bs = _polygon(len(rstd), 289.0, 0.0, height=25.0)
    res = multilaterate(bs, rstd, valid=valid)
    assert not res.ok and res.status == STATUS_TOO_FEW and word in res.reason
    assert np.all(np.isfinite(res.position))


def test_garbage_rstds_never_raise_never_nan():
    bs = _polygon(4, 289.0, 0.0, height=25.0)
    rng = np.random.default_rng(3)
    statuses = set()
    for _ in range(40):
        rstd = rng.uniform(-5e-6, 5e-6, 4)
        res = multilaterate(bs, rstd)
        statuses.add(res.status)
        assert np.all(np.isfinite(res.position)) and np.isfinite(res.residual_rms_m)
    assert statuses - {STATUS_OK} and statuses <= {STATUS_OK, STATUS_RESIDUAL, STATUS_DIVERGED,
                                                   STATUS_NO_CONVERGENCE}


@pytest.mark.parametrize("args, word", [
    ((np.zeros((3, 2)), np.zeros(3)), "bs_pos"),
    ((np.zeros((3, 3)), np.zeros(2)), "rstd_s"),
])
def test_bad_arguments_raise(args, word):
    with pytest.raises(ValueError, match=word):
        multilaterate(*args)
    with pytest.raises(ValueError, match="ref_index"):
        multilaterate(np.zeros((3, 3)), np.zeros(3), ref_index=5)
    with pytest.raises(ValueError, match="max_residual_m"):
        Multilaterator(max_residual_m=-1.0)


# -- the refinement (MINPACK lmder through leastsq, analytic Jacobian) -------------------------

#: the solver's tolerances (Multilaterator passes xtol = ftol = gtol = 1e-12)
LM_TOL = 1e-12
#: noiseless RSTDs carry a few roundings each (the 3-D norms, their difference, / c, * c), each
#: at most eps * (largest range); inside the hull the geometry amplifies them by ~GDOP < 2 per
#: residual; 32 such units bound the fix's error with margin (measured: <= 1.4)
TOL_ROUNDING_EPS_RANGES = 32


def _ranges_rstd(bs, ue, ref=0):
    d = np.linalg.norm(bs - ue, axis=1)
    return d, (d - d[ref]) / C


@pytest.mark.parametrize("n_bs", [3, 4, 5, 6])
def test_noiseless_fix_equals_the_known_position_to_float_rounding(n_bs):
    """RSTDs computed in closed form from a known point inside the hull: the fix is that point
    up to the float64 rounding of the ranges."""
    bs = _polygon(n_bs, 500.0, 90.0, height=25.0)
    rng = np.random.default_rng(100 + n_bs)
    for _ in range(25):
        r, a = rng.uniform(0.0, 240.0), rng.uniform(0.0, 2 * np.pi)   # inside every hull
        ue = np.array([r * np.cos(a), r * np.sin(a), 1.5])
        d, rstd = _ranges_rstd(bs, ue)
        res = multilaterate(bs, rstd)
        assert res.ok and not res.ambiguous
        tol = TOL_ROUNDING_EPS_RANGES * np.finfo(float).eps * d.max()
        assert np.linalg.norm(res.position - ue) <= tol
        assert res.position[2] == 1.5 and res.residual_rms_m <= tol


def test_inconsistent_rstds_fail_the_residual_check_at_the_least_squares_fix():
    """Square network (BSs at (+-R, 0), (0, +-R)), reference (R, 0), RSTDs that no point
    produces: all 0 but a 60 m excess on the opposite BS. No point has d_2 - d_0 = 60 m and
    d_1 = d_3 = d_0 (those force x = y = 0, where d_2 = d_0). The problem is symmetric in y, so
    the least-squares fix is (x*, 0) with x* the root of the whitened cost's derivative along x,
    found by bracketing (brentq) as the independent reference."""
    from scipy.optimize import brentq

    r_m, excess_m, dz2 = 400.0, 60.0, (25.0 - 1.5) ** 2
    bs = np.array([[r_m, 0, 25], [0, r_m, 25], [-r_m, 0, 25], [0, -r_m, 25.0]])
    w = np.linalg.cholesky(np.eye(3) - np.ones((3, 3)) / 4).T

    def raw(x):         # residuals (d_i - d_0) - rd_i, i = 1..3, along y = 0
        d0, d1, d2 = (np.sqrt((r_m - x) ** 2 + dz2), np.sqrt(r_m ** 2 + x ** 2 + dz2),
                      np.sqrt((r_m + x) ** 2 + dz2))
        return np.array([d1 - d0, d2 - d0 - excess_m, d1 - d0])

    def slope(x):       # d/dx of 0.5 |W raw|^2
        d0, d1, d2 = (np.sqrt((r_m - x) ** 2 + dz2), np.sqrt(r_m ** 2 + x ** 2 + dz2),
                      np.sqrt((r_m + x) ** 2 + dz2))
        g0, g1, g2 = -(r_m - x) / d0, x / d1, (r_m + x) / d2
        return (w @ raw(x)) @ (w @ np.array([g1 - g0, g2 - g0, g1 - g0]))

    x_star = brentq(slope, -r_m / 2, r_m / 2, xtol=1e-13)
    rms_star = float(np.sqrt(np.mean(raw(x_star) ** 2)))
    res = multilaterate(bs, np.array([0.0, 0.0, excess_m, 0.0]) / C)
    assert not res.ok and res.status == STATUS_RESIDUAL and "residual" in res.reason
    assert rms_star > 10.0                                      # the default max_residual_m
    # LM stops when the relative reduction of the sum of squares is below ftol: the remaining
    # step is at most sqrt(ftol) |f| / sigma_min(W J) <= sqrt(ftol) |f| GDOP
    f_norm = np.linalg.norm(w @ raw(x_star))
    tol = np.sqrt(LM_TOL) * f_norm * res.gdop
    assert abs(res.position[0] - x_star) <= tol and abs(res.position[1]) <= tol
    assert res.residual_rms_m == pytest.approx(rms_star, abs=tol)


def test_collinear_bss_report_the_mirror_twin():
    """3 BSs on the x axis: the RSTDs of (x, y) and (x, -y) are equal, so both are exact fixes;
    the solver refines the mirrored starts and reports the twin as the alternative."""
    bs = np.array([[-300.0, 0.0, 25.0], [0.0, 0.0, 25.0], [350.0, 0.0, 25.0]])
    ue = np.array([100.0, 80.0, 1.5])
    d, rstd = _ranges_rstd(bs, ue)
    res = multilaterate(bs, rstd)
    assert res.ok and res.ambiguous and len(res.alternatives) == 1
    twin = ue * [1, -1, 1]
    tol = TOL_ROUNDING_EPS_RANGES * np.finfo(float).eps * d.max()
    got = sorted([res.position, res.alternatives[0]], key=lambda p: p[1])
    assert np.linalg.norm(got[0] - twin) <= tol and np.linalg.norm(got[1] - ue) <= tol
    assert len(res.starts) % 2 == 0          # every start and its mirror image


def test_fixes_equal_scipy_least_squares_on_random_geometries():
    """Against scipy.optimize.least_squares(method="lm") with forward-difference Jacobians (the
    refinement this module used before), same whitened residuals and starts, keeping the
    lowest cost: random 4-6 BS layouts, UE near their centroid, 3 m ToA noise."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(7)
    for _ in range(60):
        n = int(rng.integers(4, 7))
        bs = np.hstack([rng.uniform(-500, 500, (n, 2)), np.full((n, 1), 25.0)])
        ue = np.append(bs[:, :2].mean(axis=0) + rng.uniform(-100, 100, 2), 1.5)
        rd = np.linalg.norm(bs - ue, axis=1) + rng.normal(0.0, 3.0, n)
        rd -= rd[0]
        res = multilaterate(bs, rd / C, max_residual_m=1e4)
        if not np.isfinite(res.gdop):
            continue
        w = np.linalg.cholesky(np.eye(n - 1) - np.ones((n - 1, n - 1)) / n).T

        def fun(xy):
            d = np.sqrt(np.sum((bs[:, :2] - xy) ** 2, axis=1) + (25.0 - 1.5) ** 2)
            return w @ ((d[1:] - d[0]) - rd[1:])

        ref = min((least_squares(fun, x0, method="lm", xtol=LM_TOL, ftol=LM_TOL, gtol=LM_TOL,
                                 max_nfev=200) for x0 in res.starts), key=lambda r: r.cost)
        assert res.ok and ref.status > 0 and not res.ambiguous
        # both stop within sqrt(ftol) |f| GDOP of the minimiser (see the test above; xtol's
        # bound, xtol |D x| ~ 1e-9 m, is far smaller); the difference is at most twice that
        tol = 2 * np.sqrt(LM_TOL) * np.linalg.norm(ref.fun) * res.gdop
        assert np.linalg.norm(res.position[:2] - ref.x) <= tol
        assert res.chi2 == 0.0 and res.residual_rms_m == pytest.approx(
            np.sqrt(np.mean(np.linalg.solve(w, ref.fun) ** 2)), abs=tol)


def test_evaluation_cap_is_no_convergence_with_minpack_count():
    """MINPACK counts the evaluation at the start and one per trial step and stops once the
    count reaches the cap: with max_nfev = 2 every start (none exact: noisy RSTDs, 5 BSs)
    stops after its first step, which is no convergence."""
    bs = _polygon(5, 500.0, 20.0, height=25.0)
    ue = np.array([60.0, -90.0, 1.5])
    d = np.linalg.norm(bs - ue, axis=1) + np.array([0.0, 3.0, -2.0, 4.0, -1.0])
    res = Multilaterator(max_nfev=2)(bs, (d - d[0]) / C)
    assert not res.ok and res.status == STATUS_NO_CONVERGENCE
    assert res.reason == ("Levenberg-Marquardt stopped: The maximum number of function "
                          "evaluations is exceeded.")
    assert res.nfev == 2 and np.all(np.isfinite(res.position))
    assert multilaterate(bs, (d - d[0]) / C).ok          # the default cap converges
