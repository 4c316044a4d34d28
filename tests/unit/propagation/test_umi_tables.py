"""The shipped TR 38.901 UMi - Street Canyon table against independent transcriptions.

``veriloc_rt/data/umi_tr38901_v18.json`` was transcribed for TR 38.901 V18.0.0 (pre-Release-19,
the UMa table's version). The oracles below were read from three public simulators and typed
in here by hand (values only; no code copied). Each is an independent transcription of the same
tables:

* SIONNA: Sionna 1.2.1 (NVlabs/sionna, ``src/sionna/phy/channel/tr38901/models/UMi_LoS.json``,
  ``UMi_NLoS.json`` and ``umi_scenario.py``): every Table 7.5-6 Part-1 UMi entry, written as
  ``a lg(b + fc) + c`` with b = 1 GHz, the Table 7.5-8 ZSD/ZOD-offset formulas, the
  Table 7.4.1-1 path loss and the Table 7.4.2-1 LoS probability, and the fc < 2 GHz -> 2 GHz
  clip (Table 7.5-6 note 7).
* NS3: ns-3 (nsnam/ns-3-dev-git, ``src/spectrum/model/three-gpp-channel-model.cc``, the
  "UMi-StreetCanyon" branch of GetThreeGppTable and the Cholesky factors ``sqrtC_UMi_LOS``
  (order SF K DS ASD ASA ZSD ZSA) / ``sqrtC_UMi_NLOS`` (SF DS ASD ASA ZSD ZSA), rounded to
  6 digits), and ``src/propagation/model/channel-condition-model.cc`` (UMi LoS probability).
  ns-3 does not clip fc at 2 GHz.
* QUADRIGA: QuaDRiGa (fraunhoferhhi/QuaDRiGa, ``quadriga_src/config/3GPP_38.901_UMi_LOS.conf``
  and ``_NLOS.conf``, which cite TR 38.901 V15.0.0): LSP coefficients in lg(1 + fc),
  decorrelation distances, cross-correlations, ZSD (without the h_UT - h_BS term, which QuaDRiGa
  leaves out), cluster constants. Its NLoS file lists 20 clusters (QuaDRiGa counts the direct
  path as a cluster, zero-power in NLoS), so it is no oracle for the NLoS cluster count; its
  per-cluster ZSD (4 deg) is not a TR 38.901 entry (7.5-20 uses 3/8 10^mu_lgZSD).

Not cross-checked (no public source found): the LOS/NLOS-state decorrelation distance of
Table 7.6.3.1-2 (50 m, marked [unverified] in the table, as UMa's). XPR (9/3 dB LoS, 8/3 dB
NLoS; all three oracles agree) is tabled but not drawn (single polarisation).
"""

import numpy as np
import pytest

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation import tr38901
from veriloc_rt.propagation.umi import UMI_TR38901_VERSION, umi_los_probability, umi_pathloss_db

# -- oracles (typed in from the sources named in the module docstring) -----------------------
#: Sionna 1.2.1 UMi_LoS.json / UMi_NLoS.json: (a, c) of a lg(1 + fc) + c for mu and sigma
SIONNA = {
    True: {"muDS": (-0.24, -7.14), "sigmaDS": (0.0, 0.38), "muASD": (-0.05, 1.21),
           "sigmaASD": (0.0, 0.41), "muASA": (-0.08, 1.73), "sigmaASA": (0.014, 0.28),
           "muZSA": (-0.1, 0.73), "sigmaZSA": (-0.04, 0.34), "muK": 9.0, "sigmaK": 5.0,
           "muXPR": 9.0, "sigmaXPR": 3.0, "sigmaSF": 4.0, "sigmaZSD": 0.35, "numClusters": 12,
           "rTau": 3.0, "zeta": 3.0, "cDS": 5.0, "cASD": 3.0, "cASA": 17.0, "cZSA": 7.0,
           "CPhiNLoS": 1.146, "CThetaNLoS": 1.104,
           "corrDist": {"DS": 7, "ASD": 8, "ASA": 8, "SF": 10, "K": 15, "ZSA": 12, "ZSD": 12},
           "corr": {"ASD_DS": 0.5, "ASA_DS": 0.8, "ASA_SF": -0.4, "ASD_SF": -0.5,
                    "DS_SF": -0.4, "ASD_ASA": 0.4, "ASD_K": -0.2, "ASA_K": -0.3, "DS_K": -0.7,
                    "SF_K": 0.5, "ZSD_SF": 0.0, "ZSA_SF": 0.0, "ZSD_K": 0.0, "ZSA_K": 0.0,
                    "ZSD_DS": 0.0, "ZSA_DS": 0.2, "ZSD_ASD": 0.5, "ZSA_ASD": 0.3,
                    "ZSD_ASA": 0.0, "ZSA_ASA": 0.0, "ZSD_ZSA": 0.0}},
    False: {"muDS": (-0.24, -6.83), "sigmaDS": (0.16, 0.28), "muASD": (-0.23, 1.53),
            "sigmaASD": (0.11, 0.33), "muASA": (-0.08, 1.81), "sigmaASA": (0.05, 0.3),
            "muZSA": (-0.04, 0.92), "sigmaZSA": (-0.07, 0.41), "muXPR": 8.0, "sigmaXPR": 3.0,
            "sigmaSF": 7.82, "sigmaZSD": 0.35, "numClusters": 19, "rTau": 2.1, "zeta": 3.0,
            "cDS": 11.0, "cASD": 10.0, "cASA": 22.0, "cZSA": 7.0, "CPhiNLoS": 1.273,
            "CThetaNLoS": 1.184,
            "corrDist": {"DS": 10, "ASD": 10, "ASA": 9, "SF": 13, "ZSA": 10, "ZSD": 10},
            "corr": {"ASD_DS": 0.0, "ASA_DS": 0.4, "ASA_SF": -0.4, "ASD_SF": 0.0,
                     "DS_SF": -0.7, "ASD_ASA": 0.0, "ZSD_SF": 0.0, "ZSA_SF": 0.0,
                     "ZSD_DS": -0.5, "ZSA_DS": 0.0, "ZSD_ASD": 0.5, "ZSA_ASD": 0.5,
                     "ZSD_ASA": 0.0, "ZSA_ASA": 0.2, "ZSD_ZSA": 0.0}},
}

#: ns-3 sqrtC_UMi_LOS, order SF K DS ASD ASA ZSD ZSA (Cholesky factor, 6 digits)
NS3_SQRTC_LOS = np.array([
    [1, 0, 0, 0, 0, 0, 0],
    [0.5, 0.866025, 0, 0, 0, 0, 0],
    [-0.4, -0.57735, 0.711805, 0, 0, 0, 0],
    [-0.5, 0.057735, 0.468293, 0.726201, 0, 0, 0],
    [-0.4, -0.11547, 0.805464, -0.23482, 0.350363, 0, 0],
    [0, 0, 0, 0.688514, 0.461454, 0.559471, 0],
    [0, 0, 0.280976, 0.231921, -0.490509, 0.11916, 0.782603]])
#: ns-3 sqrtC_UMi_NLOS, order SF DS ASD ASA ZSD ZSA (K left out)
NS3_SQRTC_NLOS = np.array([
    [1, 0, 0, 0, 0, 0],
    [-0.7, 0.714143, 0, 0, 0, 0],
    [0, 0, 1, 0, 0, 0],
    [-0.4, 0.168034, 0, 0.90098, 0, 0],
    [0, -0.70014, 0.5, 0.130577, 0.4927, 0],
    [0, 0, 0.5, 0.221981, -0.566238, 0.616522]])
#: ns-3 rounds its factors to 6 significant digits: products agree to a few 1e-6
TOL_NS3 = 2e-5

#: QuaDRiGa 3GPP_38.901_UMi_{LOS,NLOS}.conf: mu, gamma (lg(1 + fc) slope), sigma, delta
QUADRIGA = {
    True: {"DS": (-7.14, -0.24, 0.38, 0.0), "ASD": (1.21, -0.05, 0.41, 0.0),
           "ASA": (1.73, -0.08, 0.28, 0.014), "ZSA": (0.73, -0.1, 0.34, -0.04),
           "KF": (9.0, 5.0), "SF": 4.0, "ZSD": {"mu": 0.83, "min": -0.21, "A_per_km": -14.8,
                                                "sigma": 0.35},
           "r_tau": 3.0, "zeta": 3.0, "c_ds_ns": 5.0, "c_asd": 3.0, "c_asa": 17.0, "c_zsa": 7.0,
           "lambda": {"DS": 7, "K": 15, "SF": 10, "ASD": 8, "ASA": 8, "ZSD": 12, "ZSA": 12},
           "corr": {"DS_K": -0.7, "DS_SF": -0.4, "ASD_DS": 0.5, "ASA_DS": 0.8, "ZSA_DS": 0.2,
                    "SF_K": 0.5, "ASD_K": -0.2, "ASA_K": -0.3, "ASD_SF": -0.5, "ASA_SF": -0.4,
                    "ASD_ASA": 0.4, "ZSD_ASD": 0.5, "ZSA_ASD": 0.3}},
    False: {"DS": (-6.83, -0.24, 0.28, 0.16), "ASD": (1.53, -0.23, 0.33, 0.11),
            "ASA": (1.81, -0.08, 0.3, 0.05), "ZSA": (0.92, -0.04, 0.41, -0.07), "SF": 7.82,
            "ZSD": {"mu": 0.2, "min": -0.5, "A_per_km": -3.1, "sigma": 0.35},
            "r_tau": 2.1, "zeta": 3.0, "c_ds_ns": 11.0, "c_asd": 10.0, "c_asa": 22.0,
            "c_zsa": 7.0,
            "lambda": {"DS": 10, "SF": 13, "ASD": 10, "ASA": 9, "ZSD": 10, "ZSA": 10},
            "corr": {"DS_SF": -0.7, "ASA_DS": 0.4, "ZSD_DS": -0.5, "ASA_SF": -0.4,
                     "ZSD_ASD": 0.5, "ZSA_ASD": 0.5, "ZSA_ASA": 0.2}},
}

ORDER = ("SF", "K", "DS", "ASD", "ASA", "ZSD", "ZSA")
#: carriers evaluated, Hz: below the 2 GHz clip, the default 3.5 GHz, FR2
CARRIERS = (1.0e9, 3.5e9, 28e9)


def _sionna_lsp(los: bool, fc_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Sionna's mu/sigma [7] (ZSD left at 0), fc clipped at 2 GHz as its umi_scenario.py."""
    o = SIONNA[los]
    lf = np.log10(1.0 + max(fc_hz / 1e9, 2.0))
    mu, sd = np.zeros(7), np.zeros(7)
    sd[0] = o["sigmaSF"]
    if los:
        mu[1], sd[1] = o["muK"], o["sigmaK"]
    for i, n in ((2, "DS"), (3, "ASD"), (4, "ASA"), (6, "ZSA")):
        mu[i] = o[f"mu{n}"][0] * lf + o[f"mu{n}"][1]
        sd[i] = o[f"sigma{n}"][0] * lf + o[f"sigma{n}"][1]
    sd[5] = o["sigmaZSD"]
    return mu, sd


@pytest.mark.parametrize("fc", CARRIERS)
@pytest.mark.parametrize("los", [True, False], ids=["los", "nlos"])
def test_lsp_means_and_deviations_match_sionna(los, fc):
    mu, sd = tr38901.lsp_statistics("umi", los, fc, [100.0], 1.5, 10.0)
    ref_mu, ref_sd = _sionna_lsp(los, fc)
    keep = [0, 1, 2, 3, 4, 6]
    # same formula, same inputs: float rounding only
    np.testing.assert_allclose(mu[0, keep], ref_mu[keep], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sd[0], ref_sd, rtol=0, atol=1e-12)


@pytest.mark.parametrize("los", [True, False], ids=["los", "nlos"])
def test_lsp_coefficients_match_quadriga(los):
    q = QUADRIGA[los]
    fc = 3.5e9                                   # above the 2 GHz clip: QuaDRiGa has none
    lf = np.log10(1.0 + fc / 1e9)
    mu, sd = tr38901.lsp_statistics("umi", los, fc, [100.0], 1.5, 10.0)
    for i, n in ((2, "DS"), (3, "ASD"), (4, "ASA"), (6, "ZSA")):
        m0, g, s0, dl = q[n]
        assert mu[0, i] == pytest.approx(m0 + g * lf, abs=1e-12), n
        assert sd[0, i] == pytest.approx(s0 + dl * lf, abs=1e-12), n
    assert sd[0, 0] == q["SF"]
    if los:
        assert (mu[0, 1], sd[0, 1]) == q["KF"]
    cp = tr38901.cluster_parameters("umi", los, fc)
    assert (cp["r_tau"], cp["zeta_db"]) == (q["r_tau"], q["zeta"])
    assert cp["c_ds_s"] == pytest.approx(q["c_ds_ns"] * 1e-9, rel=1e-12)
    assert (cp["c_asd_deg"], cp["c_asa_deg"], cp["c_zsa_deg"]) == (q["c_asd"], q["c_asa"],
                                                                   q["c_zsa"])
    dd = dict(zip(ORDER, tr38901.decorrelation_distances_m("umi", los)))
    for n, v in q["lambda"].items():
        assert dd[n] == v, n
    c = tr38901.correlation_matrix("umi", los)
    for key, v in q["corr"].items():
        a, b = key.split("_")
        assert c[ORDER.index(a), ORDER.index(b)] == v, key
    # ZSD at h_UT = h_BS (QuaDRiGa has no height term): max(min, A d/1000 + mu)
    d = np.array([10.0, 50.0, 100.0, 400.0])
    mu_z, sd_z = tr38901.lsp_statistics("umi", los, fc, d, 10.0, 10.0)
    z = q["ZSD"]
    np.testing.assert_allclose(mu_z[:, 5], np.maximum(z["min"], z["A_per_km"] * d / 1000 + z["mu"]),
                               rtol=0, atol=1e-12)
    assert np.all(sd_z[:, 5] == z["sigma"])


@pytest.mark.parametrize("los", [True, False], ids=["los", "nlos"])
def test_cluster_constants_match_sionna_and_ns3(los):
    o = SIONNA[los]
    cp = tr38901.cluster_parameters("umi", los, 3.5e9)
    assert cp["num_clusters"] == o["numClusters"] == (12 if los else 19)   # ns-3: 12 / 19
    assert cp["rays_per_cluster"] == 20                                    # Sionna, ns-3
    assert cp["r_tau"] == o["rTau"] and cp["zeta_db"] == o["zeta"]
    assert cp["c_ds_s"] == pytest.approx(o["cDS"] * 1e-9, rel=1e-12)
    assert (cp["c_asd_deg"], cp["c_asa_deg"], cp["c_zsa_deg"]) == (o["cASD"], o["cASA"], o["cZSA"])
    assert cp["c_phi_nlos"] == o["CPhiNLoS"] and cp["c_theta_nlos"] == o["CThetaNLoS"]
    p = tr38901.scenario_table("umi")["lsp"]["los" if los else "nlos"]
    assert (p["xpr_mu_db"], p["xpr_sigma_db"]) == (o["muXPR"], o["sigmaXPR"])
    dd = dict(zip(ORDER, tr38901.decorrelation_distances_m("umi", los)))
    for n, v in o["corrDist"].items():
        assert dd[n] == v, n


@pytest.mark.parametrize("los", [True, False], ids=["los", "nlos"])
def test_cross_correlations_match_sionna_and_ns3_cholesky(los):
    c = tr38901.correlation_matrix("umi", los)
    for key, v in SIONNA[los]["corr"].items():
        a, b = key.split("_")
        assert c[ORDER.index(a), ORDER.index(b)] == v == c[ORDER.index(b), ORDER.index(a)], key
    if los:
        ref = NS3_SQRTC_LOS @ NS3_SQRTC_LOS.T
        np.testing.assert_allclose(c, ref, rtol=0, atol=TOL_NS3)
    else:
        keep = [0, 2, 3, 4, 5, 6]                   # ns-3 drops K in NLoS
        ref = NS3_SQRTC_NLOS @ NS3_SQRTC_NLOS.T
        np.testing.assert_allclose(c[np.ix_(keep, keep)], ref, rtol=0, atol=TOL_NS3)
    assert np.linalg.eigvalsh(c).min() > 0.0       # Cholesky-able


@pytest.mark.parametrize("h_ut", [1.5, 12.0, 22.5])
def test_zsd_mean_and_zod_offset_match_sionna_and_ns3(h_ut):
    """Table 7.5-8: LoS max(-0.21, -14.8 d/1000 + 0.01 |h_UT - h_BS| + 0.83); NLoS
    max(-0.5, -3.1 d/1000 + 0.01 max(h_UT - h_BS, 0) + 0.2); NLoS ZOD offset
    -10^(-1.5 lg(max(10, d)) + 3.3) (Sionna and ns-3 write the same)."""
    d = np.array([5.0, 10.0, 35.0, 100.0, 200.0, 1000.0])
    hb = 10.0
    mu_l, _ = tr38901.lsp_statistics("umi", True, 3.5e9, d, h_ut, hb)
    mu_n, _ = tr38901.lsp_statistics("umi", False, 3.5e9, d, h_ut, hb)
    np.testing.assert_allclose(mu_l[:, 5], np.maximum(-0.21, -14.8 * d / 1000
                                                      + 0.01 * abs(h_ut - hb) + 0.83), atol=1e-12)
    np.testing.assert_allclose(mu_n[:, 5], np.maximum(-0.5, -3.1 * d / 1000
                                                      + 0.01 * max(h_ut - hb, 0.0) + 0.2),
                               atol=1e-12)
    off = tr38901.zod_offset_deg("umi", False, 3.5e9, d, h_ut)
    np.testing.assert_allclose(off, -10 ** (-1.5 * np.log10(np.maximum(10.0, d)) + 3.3),
                               rtol=1e-12)
    assert off[3] == pytest.approx(-1.99526, abs=1e-5)   # by hand: -10^0.3 at 100 m
    assert np.all(tr38901.zod_offset_deg("umi", True, 3.5e9, d, h_ut) == 0.0)


def _pl_closed_form(d2, hb, hu, fc_hz, los):
    """Table 7.4.1-1 UMi - Street Canyon written out independently (Sionna/ns-3/QuaDRiGa agree):
    d'BP = 4 (hb - 1)(hu - 1) fc / c."""
    fc = fc_hz / 1e9
    d3 = np.hypot(d2, hb - hu)
    dbp = 4 * (hb - 1) * (hu - 1) * fc_hz / SPEED_OF_LIGHT
    pl1 = 32.4 + 21 * np.log10(d3) + 20 * np.log10(fc)
    pl2 = 32.4 + 40 * np.log10(d3) + 20 * np.log10(fc) - 9.5 * np.log10(dbp**2 + (hb - hu) ** 2)
    pl_los = pl1 if d2 <= dbp else pl2
    if los:
        return pl_los
    return max(pl_los, 35.3 * np.log10(d3) + 22.4 + 21.3 * np.log10(fc) - 0.3 * (hu - 1.5))


@pytest.mark.parametrize("d2", [10.0, 50.0, 150.0, 209.0, 400.0, 1500.0])
@pytest.mark.parametrize("los", [True, False], ids=["los", "nlos"])
def test_pathloss_matches_closed_form(d2, los):
    got = umi_pathloss_db(d2, 10.0, 1.5, 3.5e9, los)
    assert got == pytest.approx(_pl_closed_form(d2, 10.0, 1.5, 3.5e9, los), abs=1e-9)
    assert tr38901.pathloss_db("umi", d2, 10.0, 1.5, 3.5e9, los) == got


def test_pathloss_hand_values():
    """By hand at 3.5 GHz, h_BS 10 m, h_UT 1.5 m (d'BP = 210.1 m): 100 m LoS
    32.4 + 21 lg(100.361) + 20 lg 3.5 = 32.4 + 42.0329 + 10.8814 = 85.314 dB; NLoS
    22.4 + 35.3 lg(100.361) + 21.3 lg 3.5 = 22.4 + 70.6553 + 11.5887 = 104.644 dB."""
    assert umi_pathloss_db(100.0, 10.0, 1.5, 3.5e9, True) == pytest.approx(85.314, abs=2e-3)
    assert umi_pathloss_db(100.0, 10.0, 1.5, 3.5e9, False) == pytest.approx(104.644, abs=2e-3)
    table = tr38901.scenario_table("umi")["pathloss"]["sigma_sf_db"]
    assert (table["los"], table["nlos"]) == (4.0, 7.82)


def test_los_probability_matches_ns3_formula():
    d = np.array([0.0, 10.0, 18.0, 18.5, 36.0, 100.0, 200.0, 1000.0])
    ref = np.where(d <= 18.0, 1.0,
                   18.0 / np.maximum(d, 1e-9) + np.exp(-d / 36.0) * (1 - 18.0 / np.maximum(d, 1e-9)))
    np.testing.assert_allclose(umi_los_probability(d, 1.5), ref, rtol=0, atol=1e-12)
    # no h_UT term in UMi (UMa has one above 13 m)
    np.testing.assert_array_equal(umi_los_probability(d, 22.5), umi_los_probability(d, 1.5))
    # by hand at 100 m: 0.18 + exp(-2.7778) 0.82 = 0.18 + 0.062177 x 0.82 = 0.230985
    assert umi_los_probability(100.0, 1.5) == pytest.approx(0.230985, abs=1e-5)


def test_version_pinned_with_uma():
    tab = tr38901.scenario_table("umi")
    assert "V18.0.0" in tab["version"] and "pre-Release-19" in tab["version"]
    assert "V18.0.0" in UMI_TR38901_VERSION
    assert "V18.0.0" in tr38901.scenario_table("uma")["version"]
    assert "[unverified" in tab["los_state_decorrelation_m"]["clause"]
