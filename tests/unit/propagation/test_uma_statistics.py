"""Statistics of the TR 38.901 V18 UMa generator against Table 7.5-6 (fixed seeds).

Two levels, on purpose:
* the LSP *draws* (lg DS, lg ASA, ... SF, K) must follow the table's (clipped) normal laws:
  KS tests with the alpha = 0.001 critical value, and cross-correlations within 0.03 (Sionna's
  tolerance);
* the spreads *realised* by the generated rays (rms of the power-delay / power-angle profile) are
  not the drawn LSPs: N = 12 or 20 clusters with exponential random delays and 3 dB per-cluster
  shadowing give a realised rms DS that scatters around the drawn one (measured ratio
  q10/q50/q90 = 0.75/1.02/1.37 LoS, 0.75/0.96/1.20 NLoS at 4000 links). These get looser
  quantile checks whose bands are stated next to each assertion.
"""

import numpy as np
import pytest
from scipy import stats

from .lsp_checks import assert_clipped_normal, ring
from veriloc_rt.propagation.cir import ula_element_positions
from veriloc_rt.propagation.uma import uma_cir
from veriloc_rt.propagation.uma_lsp import draw_link_parameters
from veriloc_rt.propagation.uma_params import correlation_matrix, lsp_statistics, uma_table

FC = 3.5e9
N_LSP = 20000
#: KS critical value at alpha = 0.001 (asymptotic 1.949 / sqrt(n)); a fixed seed makes it exact
KS_CRIT_LSP = 1.949 / np.sqrt(N_LSP)
#: Sionna's tolerance for empirical cross-correlations (~4 standard errors at n = 20000)
TOL_XCORR = 0.03



@pytest.fixture(scope="module", params=[True, False], ids=["los", "nlos"])
def lsp_draws(request):
    los = request.param
    rng = np.random.default_rng(2024)
    rx = ring(N_LSP, rng, 35.0, 500.0)
    tx = np.tile([0.0, 0.0, 25.0], (N_LSP, 1, 1))
    par = draw_link_parameters(tx, rx, np.zeros((N_LSP, 1), int), FC, rng,
                               spatial_consistency=False, los_state=np.full((N_LSP, 1), los))
    return los, par



def test_lsp_draws_ks_against_table_7_5_6(lsp_draws):
    los, par = lsp_draws
    mu, sd = lsp_statistics(los, FC, [100.0], 1.5)      # DS/ASD/ASA/ZSA/SF/K: no d2D dependence
    clip = uma_table()["lsp"]["clip_deg"]
    checks = [("SF", par.sf_db[:, 0], 0, np.inf), ("DS", np.log10(par.ds[:, 0]), 2, np.inf),
              ("ASD", np.log10(par.asd[:, 0]), 3, np.log10(clip["ASD"])),
              ("ASA", np.log10(par.asa[:, 0]), 4, np.log10(clip["ASA"])),
              ("ZSA", np.log10(par.zsa[:, 0]), 6, np.log10(clip["ZSA"]))]
    if los:
        checks.append(("K", par.k_db[:, 0], 1, np.inf))
    for name, x, i, c in checks:
        assert_clipped_normal(name, x, mu[0, i], sd[0, i], c)


def test_zsd_draws_ks_given_distance(lsp_draws):
    los, par = lsp_draws
    mu, sd = lsp_statistics(los, FC, par.d_2d[:, 0], 1.5)
    assert_clipped_normal("ZSD", np.log10(par.zsd[:, 0]), mu[:, 5], sd[:, 5], np.log10(52.0))


def test_lsp_cross_correlation_matches_table(lsp_draws):
    los, par = lsp_draws
    cols = [par.sf_db[:, 0], par.k_db[:, 0] if los else None, np.log10(par.ds[:, 0]),
            np.log10(par.asd[:, 0]), np.log10(par.asa[:, 0]), None, np.log10(par.zsa[:, 0])]
    # ASA (NLoS, 9 % clipped) and ZSD (distance-dependent mean) are left out of the comparison
    keep = [i for i, c in enumerate(cols) if c is not None and not (i == 4 and not los)]
    emp = np.corrcoef(np.stack([cols[i] for i in keep]))
    ref = correlation_matrix(los)[np.ix_(keep, keep)]
    assert np.max(np.abs(emp - ref)) < TOL_XCORR


def test_los_state_frequency_matches_probability():
    n = 20000
    rng = np.random.default_rng(5)
    rx = np.tile([100.0, 0.0, 1.5], (n, 1))
    tx = np.tile([0.0, 0.0, 25.0], (n, 1, 1))
    par = draw_link_parameters(tx, rx, np.zeros((n, 1), int), FC, rng, spatial_consistency=False)
    p = 0.3477                                          # Table 7.4.2-1 at 100 m (reference)
    # 4 binomial standard deviations: fails by chance with probability 6e-5
    assert abs(par.los.mean() - p) < 4 * np.sqrt(p * (1 - p) / n)


def test_spatial_consistency_follows_decorrelation_distance():
    """Straight 1 m-step trajectory, 50 BS ids at one far site (50 independent processes), LoS
    forced. lg DS = sum_j L[DS, j] w_j with w_j OU processes of decorrelation distance d_j
    (Cholesky mixing of Table 7.5-6), so its lag-s correlation is sum_j L[DS, j]^2 exp(-s / d_j)
    (30 m for DS itself, 37 m via SF, 12 m via K, ...)."""
    n, t = 6000, 50
    rx = np.stack([np.arange(n, dtype=float), np.full(n, 2000.0), np.full(n, 1.5)], axis=-1)
    tx = np.tile([0.0, 0.0, 25.0], (n, t, 1))
    par = draw_link_parameters(tx, rx, np.tile(np.arange(t), (n, 1)), FC,
                               np.random.default_rng(9), los_state=np.ones((n, t), bool))
    x = np.log10(par.ds)
    x = x - x.mean(axis=0)
    chol = np.linalg.cholesky(correlation_matrix(True))[2]
    d_corr = np.array([37.0, 12.0, 30.0, 18.0, 15.0, 15.0, 15.0])   # SF K DS ASD ASA ZSD ZSA
    for lag in (15, 30, 60, 300):
        r = np.sum(x[:-lag] * x[lag:]) / np.sum(x * x)
        expect = np.sum(chol**2 * np.exp(-lag / d_corr))
        # Bartlett: sd of a lag correlation of an OU(30 m) over n t samples ~ sqrt(60 / (n t))
        # = 0.014; 0.06 is > 4 sd
        assert r == pytest.approx(expect, abs=0.06), lag
    # without spatial consistency consecutive points are independent
    par = draw_link_parameters(tx, rx, np.tile(np.arange(t), (n, 1)), FC,
                               np.random.default_rng(9), los_state=np.ones((n, t), bool),
                               spatial_consistency=False)
    x = np.log10(par.ds) - np.log10(par.ds).mean(axis=0)
    assert abs(np.sum(x[:-1] * x[1:]) / np.sum(x * x)) < 0.02   # 3.5 sd of 1 / sqrt(n t)


@pytest.fixture(scope="module", params=[True, False], ids=["los", "nlos"])
def realised(request):
    los = request.param
    n = 2000
    rng = np.random.default_rng(77)
    rx = ring(n, rng, 35.0, 500.0)
    tx = np.tile([0.0, 0.0, 25.0], (n, 1, 1))
    cir, par = uma_cir(tx, rx, np.zeros((n, 3)), np.zeros((n, 1, 3)), np.zeros((n, 1), int), FC,
                       ula_element_positions(1, 0.04, 0.0), rng, spatial_consistency=False,
                       los_state=np.full((n, 1), los), return_parameters=True)
    pw = cir.path_power()[:, 0]
    w = pw / pw.sum(axis=-1, keepdims=True)

    def circ_as(ang):   # TR 38.901 Annex A.1 circular angle spread, deg
        return np.degrees(np.sqrt(-2 * np.log(np.abs((w * np.exp(1j * ang)).sum(-1)))))

    tau = cir.delays[:, 0]
    m = (w * tau).sum(-1)
    out = {"DS": np.sqrt((w * (tau - m[:, None]) ** 2).sum(-1)),
           "ASA": circ_as(cir.aoa_az[:, 0]), "ASD": circ_as(cir.aod_az[:, 0]),
           "ZSA": circ_as(cir.aoa_zen[:, 0])}
    return los, cir, par, out


def test_realised_delay_spread_quantiles(realised):
    los, _, par, out = realised
    ratio = out["DS"] / par.ds[:, 0]
    q10, q50, q90 = np.quantile(ratio, [0.1, 0.5, 0.9])
    # cluster randomness: median within 15 %, 80 % of links within a factor 0.6..1.6
    assert 0.85 < q50 < 1.15 and q10 > 0.6 and q90 < 1.6
    mu, _ = lsp_statistics(los, FC, [100.0], 1.5)
    # realised median of lg DS within 0.1 decade of the table mean (-7.03 LoS, -6.44 NLoS)
    assert abs(np.median(np.log10(out["DS"])) - mu[0, 2]) < 0.1


def test_realised_angle_spreads_quantiles(realised):
    los, _, par, out = realised
    names = ["ASD", "ZSA"] + ([] if los else ["ASA"])
    for name in names:
        ratio = out[name] / getattr(par, name.lower())[:, 0]
        # measured medians 0.97-1.09: ray offsets and random jitter widen, wrapping narrows
        assert 0.8 < np.median(ratio) < 1.25, name


@pytest.mark.parametrize("realised", [True], indirect=True, ids=["los"])
def test_realised_los_asa_respects_the_k_factor_bound(realised):
    """With power fraction K/(K+1) on one ray, |sum w e^{j phi}| >= (K-1)/(K+1), so the circular
    ASA cannot exceed sqrt(-2 ln((K-1)/(K+1))) (40 deg at K = 9 dB): the drawn LoS ASA (median
    65 deg) is not realisable as a circular spread; we check the invariant instead."""
    _, _, par, out = realised
    k = 10 ** (par.k_db[:, 0] / 10)
    big = k > 1.0
    bound = np.degrees(np.sqrt(-2 * np.log((k[big] - 1) / (k[big] + 1))))
    assert np.all(out["ASA"][big] <= bound + 1e-9)


def test_realised_k_factor(realised):
    los, cir, par, _ = realised
    if not los:
        assert not cir.los.any()
        return
    pw = cir.path_power()[:, 0]
    direct = np.isclose(cir.delays[:, 0], cir.geometric_delay()[:, :1], rtol=0, atol=1e-15)
    direct &= np.abs(cir.gains[:, 0, 0].imag) <= 1e-12 * np.abs(cir.gains[:, 0, 0])
    direct &= cir.valid[:, 0]
    assert np.all(direct.sum(-1) == 1)                  # exactly one real zero-excess ray
    p_dir = (pw * direct).sum(-1)
    k_real = 10 * np.log10(p_dir / (pw.sum(-1) - p_dir))
    # the -25 dB cluster cut only removes NLoS power: realised K >= drawn, by < 0.05 dB
    dk = k_real - par.k_db[:, 0]
    assert dk.min() > -1e-9 and dk.max() < 0.05
    assert stats.kstest(k_real, "norm", args=(9.0, 3.5)).statistic < 1.949 / np.sqrt(k_real.size)
