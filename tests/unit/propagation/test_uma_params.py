"""TR 38.901 V18 (pre-Rel-19) UMa closed forms: path loss, LoS probability, ZOD offset, tables.

Reference values:
* REGRESSION_3P5GHZ: the table of /work/shared/reference/standards-and-limits.md 1b, computed
  there independently (h_BS 25 m, h_UT 1.5 m, h_E 1 m, c = 299 792 458 m/s), printed to 0.01 dB
  and 1e-4 in probability.
* The ``*_by_hand`` tests re-derive a few values here from the formula text of Table 7.4.1-1
  with the spec's c = 3e8 m/s, written out with ``math`` only.
"""

import math

import numpy as np
import pytest

from veriloc_rt.propagation.uma import uma_los_probability, uma_pathloss_db
from veriloc_rt.propagation.uma_params import (TR38901_VERSION, cluster_parameters,
                                               correlation_matrix, lsp_statistics, uma_table,
                                               zod_offset_deg)

FC = 3.5e9
#: The reference table is rounded to 0.01 dB: half a unit of the last digit plus float noise
TOL_TABLE_DB = 0.0051
#: Probabilities are rounded to 1e-4
TOL_TABLE_PROB = 0.51e-4
#: c = 3e8 (spec text) vs 299 792 458 (code) moves d'BP by 0.07 %: < 0.006 dB at 5 km
TOL_C_CONVENTION_DB = 0.01

# d2D (m), PL_LOS, PL_NLOS (dB), Pr_LOS
REGRESSION_3P5GHZ = [
    (10, 69.84, 79.42, 1.0000),
    (35, 74.63, 87.92, 0.7930),
    (100, 83.14, 103.04, 0.3477),
    (500, 98.27, 129.92, 0.0363),
    (1000, 109.41, 141.67, 0.0180),
    (5000, 137.36, 168.98, 0.0036),
]


@pytest.mark.parametrize("d, pl_los, pl_nlos, pr_los", REGRESSION_3P5GHZ)
def test_tr38901_v18_pathloss_regression_table(d, pl_los, pl_nlos, pr_los):
    assert uma_pathloss_db(d, 25.0, 1.5, FC, True) == pytest.approx(pl_los, abs=TOL_TABLE_DB)
    assert uma_pathloss_db(d, 25.0, 1.5, FC, False) == pytest.approx(pl_nlos, abs=TOL_TABLE_DB)
    assert float(uma_los_probability(d, 1.5)) == pytest.approx(pr_los, abs=TOL_TABLE_PROB)


def test_pathloss_los_beyond_breakpoint_by_hand():
    # d2D = 1000 m > d'BP = 4 * 24 * 0.5 * 3.5e9 / 3e8 = 560 m: PL2 branch
    d3 = math.sqrt(1000.0**2 + 23.5**2)
    d_bp = 4 * 24.0 * 0.5 * 3.5e9 / 3e8
    expect = 28.0 + 40 * math.log10(d3) + 20 * math.log10(3.5) - 9 * math.log10(d_bp**2 + 23.5**2)
    assert uma_pathloss_db(1000.0, 25.0, 1.5, FC, True) == pytest.approx(expect,
                                                                          abs=TOL_C_CONVENTION_DB)


def test_pathloss_los_before_breakpoint_by_hand():
    d3 = math.sqrt(300.0**2 + 23.5**2)
    expect = 28.0 + 22 * math.log10(d3) + 20 * math.log10(3.5)
    assert uma_pathloss_db(300.0, 25.0, 1.5, FC, True) == pytest.approx(expect, abs=1e-9)


def test_pathloss_nlos_tall_ue_2ghz_by_hand():
    # h_UT = 10 m, fc = 2 GHz, d2D = 200 m: PL'_NLOS dominates PL_LOS
    d3 = math.sqrt(200.0**2 + 15.0**2)
    nlos = 13.54 + 39.08 * math.log10(d3) + 20 * math.log10(2.0) - 0.6 * (10.0 - 1.5)
    los = 28.0 + 22 * math.log10(d3) + 20 * math.log10(2.0)   # d'BP = 4*24*9*2e9/3e8 = 5760 m
    assert nlos > los
    assert uma_pathloss_db(200.0, 25.0, 10.0, 2e9, False) == pytest.approx(nlos, abs=1e-9)


def test_pathloss_nlos_is_never_below_los():
    d = np.geomspace(10, 5000, 200)
    assert np.all(uma_pathloss_db(d, 25.0, 1.5, FC, False) >= uma_pathloss_db(d, 25.0, 1.5, FC, True))


def test_pathloss_array_and_scalar_agree():
    d = np.array([50.0, 700.0])
    arr = uma_pathloss_db(d, 25.0, 1.5, FC, True)
    assert arr.shape == (2,)
    assert arr[1] == uma_pathloss_db(700.0, 25.0, 1.5, FC, True)
    assert isinstance(uma_pathloss_db(700.0, 25.0, 1.5, FC, True), float)


def test_los_probability_tall_ue_by_hand():
    d, h = 120.0, 18.0
    c = ((h - 13) / 10) ** 1.5
    expect = (18 / d + math.exp(-d / 63) * (1 - 18 / d)) * (1 + c * 1.25 * (d / 100) ** 3
                                                           * math.exp(-d / 150))
    assert float(uma_los_probability(d, h)) == pytest.approx(expect, rel=1e-12)


def test_zod_offset_reference_values():
    # standards-and-limits.md 1b: -4.88 deg at 100 m, -1.80 deg at 500 m (rounded to 0.01)
    got = zod_offset_deg(False, FC, [100.0, 500.0], 1.5)
    np.testing.assert_allclose(got, [-4.88, -1.80], atol=0.0051)
    assert np.all(zod_offset_deg(True, FC, [100.0], 1.5) == 0)


def test_lsp_medians_at_3p5ghz_use_the_6ghz_clip():
    # reference medians (fc < 6 GHz -> 6 GHz): DS 93.3 / 364 ns, ASD 14.0 / 25.8 deg,
    # ASA 64.6 / 74.1 deg, ZSA 8.9 / 18.2 deg, c_DS 3.91 ns
    mu_l, _ = lsp_statistics(True, FC, [100.0], 1.5)
    mu_n, _ = lsp_statistics(False, FC, [100.0], 1.5)
    np.testing.assert_allclose(10 ** mu_l[0, [2, 3, 4, 6]] * [1e9, 1, 1, 1],
                               [93.3, 14.0, 64.6, 8.9], rtol=0.006)
    np.testing.assert_allclose(10 ** mu_n[0, [2, 3, 4, 6]] * [1e9, 1, 1, 1],
                               [364, 25.8, 74.1, 18.2], rtol=0.006)
    assert cluster_parameters(True, FC)["c_ds_s"] == pytest.approx(3.91e-9, abs=0.006e-9)


def test_ray_offsets_not_sionna_0_1481_bug():
    """Table 7.5-3: +-1.1481, not the -0.1481 of Sionna rays.py (NVlabs/sionna#1107)."""
    a = np.array(uma_table()["ray_offsets"]["values"])
    assert a.size == 20 and abs(a.sum()) < 1e-12
    np.testing.assert_array_equal(np.sort(a[a > 0]), np.sort(-a[a < 0]))
    assert 1.1481 in a and -1.1481 in a and -0.1481 not in a


def test_subcluster_ray_groups_partition_the_rays():
    groups = uma_table()["subclusters"]["rays_1based"]
    assert sorted(sum(groups, [])) == list(range(1, 21))
    assert [len(g) for g in groups] == [10, 6, 4]          # powers 10/20, 6/20, 4/20


@pytest.mark.parametrize("los, min_eig", [(True, 0.0026), (False, 0.016)])
def test_cross_correlation_matrices_positive_definite(los, min_eig):
    c = correlation_matrix(los)
    np.testing.assert_array_equal(c, c.T)
    # smallest eigenvalues from the reference (V-calc): LOS 0.0026, NLOS 0.016 (rounded)
    assert np.linalg.eigvalsh(c).min() == pytest.approx(min_eig, abs=0.0005)
    np.linalg.cholesky(c)


def test_tables_pinned_pre_release_19():
    assert "V18" in TR38901_VERSION and "V18" in uma_table()["version"]
    assert "pre-Release-19" in uma_table()["version"]
    # V19 changed UMa NLOS mu_lgDS to -6.47 - 0.134 lg(fc); the pinned value is -6.28 - 0.204
    assert uma_table()["lsp"]["nlos"]["mu_lgDS"] == [-6.28, -0.204]


@pytest.mark.parametrize("kwargs, exc", [
    ({"d_2d_m": -1.0}, ValueError), ({"fc_hz": 0.0}, ValueError),
    ({"h_ut_m": 1.0}, ValueError), ({"los": 1}, TypeError),
])
def test_pathloss_rejects_bad_arguments(kwargs, exc):
    args = {"d_2d_m": 100.0, "h_bs_m": 25.0, "h_ut_m": 1.5, "fc_hz": FC, "los": True}
    args.update(kwargs)
    with pytest.raises(exc, match=next(iter(kwargs))):
        uma_pathloss_db(**args)
