"""TR 38.901 scenario tables (UMa, UMi - Street Canyon): path loss, LoS probability, LSP statistics.

One evaluator per quantity, parametrised by a scenario's shipped table
(``veriloc_rt/data/<scenario>_tr38901_v18.json``); the random draws that use them live in
:mod:`veriloc_rt.propagation.uma_lsp` and :mod:`veriloc_rt.propagation.uma_clusters`, which take
the scenario name. Where the scenarios differ in the *form* of a formula, the table says which:

* frequency-dependent LSP entries are ``a + b lg(fc_offset + max(fc, fc_min))`` with fc in GHz:
  UMa ``lg(fc)`` clipped at 6 GHz (Table 7.5-6 note 6), UMi ``lg(1 + fc)`` clipped at 2 GHz
  (note 7). A standard deviation is a number or such an ``[a, b]`` pair (UMi's are
  frequency-dependent);
* the ZSD log-mean (Tables 7.5-7, 7.5-8) is ``max(floor, slope d2D/1000 + height_slope h + const)``
  with ``h`` = ``h_UT - 1.5`` (UMa), ``|h_UT - h_BS|`` (UMi LoS) or ``max(h_UT - h_BS, 0)``
  (UMi NLoS);
* the NLoS ZOD offset is ``A lg fc + B - 10^((C lg fc + D) lg(max(d_min, d2D)) + E lg fc + F
  + G (h_UT - 1.5))``: UMa's Table 7.5-7 form, UMi's Table 7.5-8 ``-10^(-1.5 lg(max(10, d2D))
  + 3.3)`` with A = B = C = E = G = 0;
* the LoS probability (Table 7.4.2-1) is ``18/d + exp(-d/d1)(1 - 18/d)`` times UMa's h_UT term,
  which UMi does not have.

Both tables are pinned to TR 38.901 V18.0.0 (pre-Release-19; :data:`TR38901_VERSIONS`).
Conventions: distances in m, ``fc_hz`` in Hz (converted to GHz inside), ``lg`` = log10 with the
delay spread in s and the angle spreads in degrees (the tables' units).
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import numpy as np

from .pathloss_models import tr38901_pathloss_db, umi_table

__all__ = ["SCENARIOS", "SCENARIO_NAMES", "TR38901_VERSIONS", "LSP_ORDER", "scenario_table",
           "pathloss_db", "los_probability", "lsp_statistics", "zod_offset_deg",
           "correlation_matrix", "decorrelation_distances_m", "cluster_parameters"]

#: The stochastic scenarios with a shipped table
SCENARIOS = ("uma", "umi")
#: Their names as TR 38.901 writes them
SCENARIO_NAMES = {"uma": "UMa", "umi": "UMi-Street Canyon"}
#: The TR 38.901 version each shipped table is pinned to
TR38901_VERSIONS = {"uma": "V18.0.0 (pre-Rel-19 UMa; V14.1.0-V18.x agree)",
                    "umi": "V18.0.0 (pre-Rel-19 UMi-Street Canyon; V15.0.0-V18.x agree)"}

#: LSP order of the cross-correlation matrices and of every ``[..., 7]`` LSP array
LSP_ORDER = ("SF", "K", "DS", "ASD", "ASA", "ZSD", "ZSA")


@lru_cache(maxsize=1)
def _uma_table() -> dict:
    text = resources.files("veriloc_rt").joinpath("data", "uma_tr38901_v18.json").read_text()
    return json.loads(text)


def scenario_table(scenario: str) -> dict:
    """The shipped table of ``scenario`` (parsed JSON, cached; treat as read-only)."""
    if scenario == "uma":
        return _uma_table()
    if scenario == "umi":
        return umi_table()
    raise ValueError(f"Argument `scenario` must be one of {SCENARIOS}, not {scenario!r}")


def pathloss_db(scenario: str, d_2d_m, h_bs_m, h_ut_m, fc_hz, los):
    """Basic path loss of Table 7.4.1-1 (no shadowing), h_E = 1 m; see
    :func:`~veriloc_rt.propagation.pathloss_models.tr38901_pathloss_db`."""
    return tr38901_pathloss_db(scenario_table(scenario)["pathloss"], d_2d_m, h_bs_m, h_ut_m,
                               fc_hz, los)


def los_probability(scenario: str, d_2d_m, h_ut_m) -> np.ndarray:
    """LoS probability of Table 7.4.2-1, outdoor UE.

    Pr = 1 for d2D <= 18 m, else [18/d + exp(-d/d1)(1 - 18/d)] (1 + C'(h_UT) 5/4 (d/100)^3
    exp(-d/150)); d1 = 63 m (UMa), 36 m (UMi); C' (UMa only) = 0 for h_UT <= 13 m and
    ((h_UT - 13)/10)^1.5 up to 23 m.

    :param d_2d_m: [...] float64, m; h_ut_m: [...] float64, m
    :returns: [...] float64, probability in [0, 1]
    """
    t = scenario_table(scenario)["los_probability"]
    d = np.asarray(d_2d_m, dtype=float)
    hu = np.asarray(h_ut_m, dtype=float)
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"Argument `d_2d_m` must be finite and >= 0, not {d_2d_m!r}")
    dd = np.maximum(d, t["d_near_m"])
    base = t["d_near_m"] / dd + np.exp(-dd / t["d_decay_m"]) * (1.0 - t["d_near_m"] / dd)
    if "h_ut_threshold_m" in t:      # UMa's tall-UE term
        c_prime = np.where(hu <= t["h_ut_threshold_m"], 0.0,
                           (np.clip(hu - t["h_ut_threshold_m"], 0, None) / t["h_ut_scale_m"])
                           ** t["h_ut_exponent"])
        base = base * (1.0 + c_prime * t["gain"] * (dd / t["d_scale_m"]) ** 3
                       * np.exp(-dd / t["d_exp_m"]))
    return np.where(d <= t["d_near_m"], 1.0, np.clip(base, 0.0, 1.0))


def _lg_fc(scenario: str, fc_hz: float) -> float:
    """lg of the carrier the frequency-dependent LSP entries use (Table 7.5-6 notes 6 and 7)."""
    lsp = scenario_table(scenario)["lsp"]
    fc = max(fc_hz / 1e9, lsp["fc_min_ghz"])
    offset = lsp.get("fc_offset_ghz")
    return float(np.log10(fc if offset is None else offset + fc))


def _linear(entry, lf: float) -> float:
    """A table entry: a number, or ``[a, b]`` meaning a + b lf."""
    if isinstance(entry, list):
        a, b = entry
        return a + b * lf
    return entry


def _height_term(kind: str, h_ut: np.ndarray, h_bs: np.ndarray | None) -> np.ndarray:
    if kind == "h_ut-1.5":
        return h_ut - 1.5
    if h_bs is None:
        raise ValueError("Argument `h_bs_m` is needed by this scenario's ZSD (Table 7.5-8)")
    if kind == "abs(h_ut-h_bs)":
        return np.abs(h_ut - h_bs)
    if kind == "max(h_ut-h_bs,0)":
        return np.maximum(h_ut - h_bs, 0.0)
    raise ValueError(f"unknown ZSD height term {kind!r} in the shipped table")


def lsp_statistics(scenario: str, los: bool, fc_hz: float, d_2d_m, h_ut_m,
                   h_bs_m=None) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the seven LSPs in :data:`LSP_ORDER` (Tables 7.5-6/7/8).

    SF and K are in dB; DS, ASD, ASA, ZSD, ZSA in lg units (DS in s, angles in deg). For NLoS
    the K entries are unused zeros (0, 0): K does not exist there.

    :param d_2d_m, h_ut_m: [L] float64, m (ZSD depends on them)
    :param h_bs_m: [L] float64, m (UMi's ZSD depends on it; UMa ignores it)
    :returns: (mu, sigma), each [L, 7] float64
    """
    tab = scenario_table(scenario)
    p = tab["lsp"]["los" if los else "nlos"]
    z = tab["zsd"]["los" if los else "nlos"]
    lf = _lg_fc(scenario, fc_hz)
    d2 = np.atleast_1d(np.asarray(d_2d_m, dtype=float))
    hu = np.broadcast_to(np.asarray(h_ut_m, dtype=float), d2.shape)
    hb = None if h_bs_m is None else np.broadcast_to(np.asarray(h_bs_m, dtype=float), d2.shape)
    height = _height_term(z["height_term"], hu, hb)
    mu_zsd = np.maximum(z["floor"], z["d2d_slope_per_km"] * d2 / 1000.0
                        + z["height_slope"] * height + z["const"])
    mu = np.zeros(d2.shape + (7,))
    sd = np.zeros(d2.shape + (7,))
    sd[:, 0] = p["sigma_SF_db"]
    if los:
        mu[:, 1], sd[:, 1] = p["mu_K_db"], p["sigma_K_db"]
    for i, name in ((2, "DS"), (3, "ASD"), (4, "ASA"), (6, "ZSA")):
        mu[:, i], sd[:, i] = _linear(p[f"mu_lg{name}"], lf), _linear(p[f"sigma_lg{name}"], lf)
    mu[:, 5], sd[:, 5] = mu_zsd, z["sigma"]
    return mu, sd


def zod_offset_deg(scenario: str, los: bool, fc_hz: float, d_2d_m, h_ut_m) -> np.ndarray:
    """NLoS ZOD offset mu_offset,ZOD of Table 7.5-7 (UMa) / 7.5-8 (UMi); 0 for LoS.

    :returns: [L] float64, deg
    """
    d2 = np.atleast_1d(np.asarray(d_2d_m, dtype=float))
    if los:
        return np.zeros_like(d2)
    c = scenario_table(scenario)["zsd"]["zod_offset"]
    lf = _lg_fc(scenario, fc_hz)
    hu = np.broadcast_to(np.asarray(h_ut_m, dtype=float), d2.shape)
    expo = ((c["slope_lg_fc"] * lf + c["slope"]) * np.log10(np.maximum(c["d_min_m"], d2))
            + c["expo_lg_fc"] * lf + c["expo_const"] + c["expo_h_ut"] * (hu - 1.5))
    return c["lg_fc"] * lf + c["const"] - 10.0**expo


def correlation_matrix(scenario: str, los: bool) -> np.ndarray:
    """Cross-correlation matrix of the LSPs in :data:`LSP_ORDER` (Table 7.5-6).

    For NLoS the K row and column are the identity (K is not used).

    :returns: [7, 7] float64, symmetric, unit diagonal
    """
    cc = scenario_table(scenario)["lsp"]["los" if los else "nlos"]["cross_correlation"]
    c = np.eye(7)
    for key, val in cc.items():
        a, b = key.split("_")
        i, j = LSP_ORDER.index(a), LSP_ORDER.index(b)
        c[i, j] = c[j, i] = val
    return c


def decorrelation_distances_m(scenario: str, los: bool) -> np.ndarray:
    """Decorrelation distances of the LSPs in :data:`LSP_ORDER` (Table 7.5-6).

    :returns: [7] float64, m (K for NLoS: 1 m, unused)
    """
    dd = scenario_table(scenario)["lsp"]["los" if los else "nlos"]["decorrelation_m"]
    return np.array([float(dd.get(n, 1.0)) for n in LSP_ORDER])


def cluster_parameters(scenario: str, los: bool, fc_hz: float) -> dict:
    """Per-condition fast-fading constants (Tables 7.5-6, 7.5-2, 7.5-4).

    :returns: dict with ``num_clusters``, ``rays_per_cluster``, ``r_tau``, ``zeta_db``,
        ``c_ds_s`` (s), ``c_asd_deg``, ``c_asa_deg``, ``c_zsa_deg``, ``c_phi_nlos``, ``c_theta_nlos``
    """
    tab = scenario_table(scenario)
    p = tab["lsp"]["los" if los else "nlos"]
    a, b, floor = p["c_ds_ns"]
    c_ds_ns = max(floor, a + b * _lg_fc(scenario, fc_hz))
    n = int(p["num_clusters"])
    return {
        "num_clusters": n, "rays_per_cluster": int(p["rays_per_cluster"]),
        "r_tau": float(p["r_tau"]), "zeta_db": float(p["zeta_db"]), "c_ds_s": c_ds_ns * 1e-9,
        "c_asd_deg": float(p["c_asd_deg"]), "c_asa_deg": float(p["c_asa_deg"]),
        "c_zsa_deg": float(p["c_zsa_deg"]),
        "c_phi_nlos": float(tab["c_phi_nlos"][str(n)]),
        "c_theta_nlos": float(tab["c_theta_nlos"][str(n)]),
    }
