"""Statistics of the TR 38.901 UMi - Street Canyon draws against the table (fixed seeds).

The draws share the UMa procedure (tests/unit/propagation/test_uma_statistics.py); these tests
check that the UMi table is what drives them:

* every LSP draw (SF, K, lg DS, lg ASD, lg ASA, lg ZSA, lg ZSD) follows its (clipped) normal law
  with the Table 7.5-6 / 7.5-8 UMi mean and deviation: KS at alpha = 0.001;
* the cross-correlations equal those of an independent generator (numpy's multivariate normal on
  ns-3's Cholesky factor of the UMi matrix, clipped the same way): UMi's ASA is clipped at 104 deg
  on 12 % (LoS) / 22 % (NLoS) of the links at 3.5 GHz, which moves its Pearson correlations by
  up to 0.02 from the table's, so the reference must be clipped too;
* the LoS state frequency equals Table 7.4.2-1's probability;
* the spatial correlation of lg DS follows UMi's 7 m (LoS) decorrelation distance;
* the UMa draws are unchanged by the scenario parameter (same stream, same numbers).
"""

import numpy as np
import pytest

from .lsp_checks import assert_clipped_normal, ring
from veriloc_rt.propagation import tr38901
from veriloc_rt.propagation.cir import ula_element_positions
from veriloc_rt.propagation.uma import uma_cir
from veriloc_rt.propagation.uma_lsp import draw_link_parameters
from veriloc_rt.propagation.umi import umi_cir

FC = 3.5e9
N_LSP = 20000
H_BS = 10.0
#: difference of two sample correlations at n = 20000 each: sd <= sqrt(2 / n) = 0.01; 0.03 is
#: > 3 sd (and Sionna's own tolerance for this check)
TOL_XCORR = 0.03
#: ns-3 Cholesky factors of the UMi matrices (see test_umi_tables.py for the source)
NS3_LOS = np.array([
    [1, 0, 0, 0, 0, 0, 0], [0.5, 0.866025, 0, 0, 0, 0, 0],
    [-0.4, -0.57735, 0.711805, 0, 0, 0, 0], [-0.5, 0.057735, 0.468293, 0.726201, 0, 0, 0],
    [-0.4, -0.11547, 0.805464, -0.23482, 0.350363, 0, 0],
    [0, 0, 0, 0.688514, 0.461454, 0.559471, 0],
    [0, 0, 0.280976, 0.231921, -0.490509, 0.11916, 0.782603]])
NS3_NLOS = np.array([
    [1, 0, 0, 0, 0, 0], [-0.7, 0.714143, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0],
    [-0.4, 0.168034, 0, 0.90098, 0, 0], [0, -0.70014, 0.5, 0.130577, 0.4927, 0],
    [0, 0, 0.5, 0.221981, -0.566238, 0.616522]])



@pytest.fixture(scope="module", params=[True, False], ids=["los", "nlos"])
def lsp_draws(request):
    los = request.param
    rng = np.random.default_rng(2024)
    rx = ring(N_LSP, rng, 10.0, 300.0)
    tx = np.tile([0.0, 0.0, H_BS], (N_LSP, 1, 1))
    par = draw_link_parameters(tx, rx, np.zeros((N_LSP, 1), int), FC, rng,
                               spatial_consistency=False, los_state=np.full((N_LSP, 1), los),
                               scenario="umi")
    return los, par



def test_lsp_draws_ks_against_umi_table(lsp_draws):
    los, par = lsp_draws
    mu, sd = tr38901.lsp_statistics("umi", los, FC, par.d_2d[:, 0], 1.5, H_BS)
    clip = tr38901.scenario_table("umi")["lsp"]["clip_deg"]
    checks = [("SF", par.sf_db[:, 0], 0, np.inf), ("DS", np.log10(par.ds[:, 0]), 2, np.inf),
              ("ASD", np.log10(par.asd[:, 0]), 3, np.log10(clip["ASD"])),
              ("ASA", np.log10(par.asa[:, 0]), 4, np.log10(clip["ASA"])),
              ("ZSD", np.log10(par.zsd[:, 0]), 5, np.log10(clip["ZSD"])),
              ("ZSA", np.log10(par.zsa[:, 0]), 6, np.log10(clip["ZSA"]))]
    if los:
        checks.append(("K", par.k_db[:, 0], 1, np.inf))
    for name, x, i, c in checks:
        assert_clipped_normal(name, x, mu[:, i], sd[:, i], c)
    # the table's numbers, by hand at 3.5 GHz (lg(1 + 3.5) = 0.65321): LoS lg DS mean
    # -7.14 - 0.24 x 0.65321 = -7.2968 (50 ns), NLoS sd 0.28 + 0.16 x 0.65321 = 0.38451
    if los:
        assert mu[0, 2] == pytest.approx(-7.2968, abs=1e-4)
    else:
        assert sd[0, 2] == pytest.approx(0.38451, abs=1e-5)


def test_lsp_moments_against_umi_table(lsp_draws):
    """Moment test on the unclipped LSPs: sample mean within 4 standard errors, sample sd within
    4 standard errors (sd / sqrt(2 n)) of the table's."""
    los, par = lsp_draws
    mu, sd = tr38901.lsp_statistics("umi", los, FC, [100.0], 1.5, H_BS)
    for name, x, i in (("SF", par.sf_db[:, 0], 0), ("DS", np.log10(par.ds[:, 0]), 2)):
        n = x.size
        assert abs(x.mean() - mu[0, i]) < 4 * sd[0, i] / np.sqrt(n), name
        assert abs(x.std(ddof=1) - sd[0, i]) < 4 * sd[0, i] / np.sqrt(2 * n), name


def test_lsp_cross_correlation_matches_clipped_reference(lsp_draws):
    los, par = lsp_draws
    clip = tr38901.scenario_table("umi")["lsp"]["clip_deg"]
    mu, sd = tr38901.lsp_statistics("umi", los, FC, par.d_2d[:, 0], 1.5, H_BS)
    # independent generator: N(0, L L^T) with ns-3's factor, scaled, clipped in lg units
    order = [0, 1, 2, 3, 4, 5, 6] if los else [0, 2, 3, 4, 5, 6]
    chol = NS3_LOS if los else NS3_NLOS
    g = np.random.default_rng(99).standard_normal((N_LSP, len(order))) @ chol.T
    ref = {}
    for k, i in enumerate(order):
        v = mu[:, i] + sd[:, i] * g[:, k]
        name = tr38901.LSP_ORDER[i]
        ref[i] = np.minimum(v, np.log10(clip[name])) if name in clip else v
    drawn = {0: par.sf_db[:, 0], 2: np.log10(par.ds[:, 0]), 3: np.log10(par.asd[:, 0]),
             4: np.log10(par.asa[:, 0]), 6: np.log10(par.zsa[:, 0])}
    if los:
        drawn[1] = par.k_db[:, 0]
    keep = sorted(drawn)          # ZSD left out: its mean depends on distance (checked by KS)
    emp = np.corrcoef(np.stack([drawn[i] for i in keep]))
    exp = np.corrcoef(np.stack([ref[i] for i in keep]))
    assert np.max(np.abs(emp - exp)) < TOL_XCORR
    # and the reference itself reproduces the table away from the clipped ASA
    table = tr38901.correlation_matrix("umi", los)
    sub = [i for i in keep if i != 4]
    exp_sub = np.corrcoef(np.stack([ref[i] for i in sub]))
    assert np.max(np.abs(exp_sub - table[np.ix_(sub, sub)])) < TOL_XCORR


@pytest.mark.parametrize("d", [30.0, 100.0, 250.0])
def test_los_state_frequency_matches_probability(d):
    n = 20000
    rng = np.random.default_rng(5)
    rx = np.tile([d, 0.0, 1.5], (n, 1))
    tx = np.tile([0.0, 0.0, H_BS], (n, 1, 1))
    par = draw_link_parameters(tx, rx, np.zeros((n, 1), int), FC, rng, spatial_consistency=False,
                               scenario="umi")
    p = 18.0 / d + np.exp(-d / 36.0) * (1 - 18.0 / d)        # Table 7.4.2-1, UMi
    # 4 binomial standard deviations: fails by chance with probability 6e-5
    assert abs(par.los.mean() - p) < 4 * np.sqrt(p * (1 - p) / n)


def test_spatial_consistency_follows_umi_decorrelation_distances():
    """lg DS = sum_j L[DS, j] w_j with OU processes of Table 7.5-6 UMi LoS decorrelation
    distances (SF 10, K 15, DS 7, ASD 8, ASA 8, ZSD 12, ZSA 12 m): lag-s correlation
    sum_j L[DS, j]^2 exp(-s / d_j)."""
    n, t = 4000, 50
    rx = np.stack([np.arange(n, dtype=float) * 0.5, np.full(n, 150.0), np.full(n, 1.5)], axis=-1)
    tx = np.tile([0.0, 0.0, H_BS], (n, t, 1))
    par = draw_link_parameters(tx, rx, np.tile(np.arange(t), (n, 1)), FC,
                               np.random.default_rng(9), los_state=np.ones((n, t), bool),
                               scenario="umi")
    x = np.log10(par.ds)
    x = x - x.mean(axis=0)
    chol = np.linalg.cholesky(tr38901.correlation_matrix("umi", True))[2]
    d_corr = np.array([10.0, 15.0, 7.0, 8.0, 8.0, 12.0, 12.0])
    for lag in (4, 14, 40):                        # 2, 7, 20 m at 0.5 m steps
        r = np.sum(x[:-lag] * x[lag:]) / np.sum(x * x)
        expect = np.sum(chol**2 * np.exp(-lag * 0.5 / d_corr))
        # Bartlett: sd of a lag correlation over n t samples of ~ 20-sample memory ~ 0.01; 0.05
        # is > 4 sd
        assert r == pytest.approx(expect, abs=0.05), lag


def test_umi_cir_clusters_and_meta():
    n = 400
    rng = np.random.default_rng(3)
    rx = ring(n, rng, 10.0, 300.0)
    tx = np.tile([0.0, 0.0, H_BS], (n, 1, 1))
    for los, clusters in ((True, 12), (False, 19)):
        cir, par = umi_cir(tx, rx, np.zeros((n, 3)), np.zeros((n, 1, 3)), np.zeros((n, 1), int),
                           FC, ula_element_positions(2, 0.04, 0.0), np.random.default_rng(4),
                           spatial_consistency=False, los_state=np.full((n, 1), los),
                           return_parameters=True)
        # N clusters x 20 rays (+ the direct ray in LoS) before the -25 dB cut
        assert cir.delays.shape[-1] == clusters * 20 + (1 if los else 0)
        assert cir.meta["model"] == "3GPP TR 38.901 UMi-Street Canyon"
        assert "V18.0.0" in cir.meta["tr38901_version"]
        # total power = path loss + shadow fading: the ray powers sum to 1 per link, less the
        # clusters cut at -25 dB (each < 0.32 % of the strongest, at most N - 1 of them: < 0.3 dB)
        pl = -10 * np.log10(cir.path_power()[:, 0].sum(-1))
        excess = pl - (par.pathloss_db[:, 0] + par.sf_db[:, 0])
        assert np.all(excess > -1e-9) and np.all(excess < 0.3)


def test_uma_draws_do_not_depend_on_the_new_parameter():
    """scenario='uma' explicitly and by default give the same numbers from the same stream."""
    n = 200
    rx = ring(n, np.random.default_rng(1), 35.0, 500.0)
    tx = np.tile([0.0, 0.0, 25.0], (n, 1, 1))
    args = (tx, rx, np.zeros((n, 3)), np.zeros((n, 1, 3)), np.zeros((n, 1), int), FC,
            ula_element_positions(2, 0.04, 0.0))
    a = uma_cir(*args, np.random.default_rng(8))
    b = uma_cir(*args, np.random.default_rng(8), scenario="uma")
    c = uma_cir(*args, np.random.default_rng(8), scenario="umi")
    np.testing.assert_array_equal(a.gains, b.gains)
    assert not np.array_equal(np.abs(a.gains).sum(), np.abs(c.gains).sum())
