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
