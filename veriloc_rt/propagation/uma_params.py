"""TR 38.901 UMa closed-form parameters: path loss, LoS probability and LSP statistics.

All numbers come from ``veriloc_rt/data/uma_tr38901_v18.json`` (TR 38.901 V18.0.0, identical in
V14.1.0 to V18.x; pinned pre-Release-19). This module only evaluates the tables; the random draws
live in :mod:`veriloc_rt.propagation.uma_lsp` and :mod:`veriloc_rt.propagation.uma_clusters`.

Conventions: distances in m, ``fc_hz`` in Hz (converted to GHz inside, as the tables use),
``lg`` = log10 with the delay spread in s and the angle spreads in degrees (the tables' units).
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import numpy as np

from .pathloss_models import breakpoint_distance, tr38901_pathloss_db  # noqa: F401 (re-export)

#: The TR 38.901 version the shipped tables are pinned to
TR38901_VERSION = "V18.0.0 (pre-Rel-19 UMa; V14.1.0-V18.x agree)"

#: LSP order of the cross-correlation matrices and of every ``[..., 7]`` LSP array
LSP_ORDER = ("SF", "K", "DS", "ASD", "ASA", "ZSD", "ZSA")


@lru_cache(maxsize=1)
def uma_table() -> dict:
    """The shipped UMa table (parsed JSON, cached; treat as read-only)."""
    text = resources.files("veriloc_rt").joinpath("data", "uma_tr38901_v18.json").read_text()
    return json.loads(text)


def uma_pathloss_db(d_2d_m, h_bs_m, h_ut_m, fc_hz, los: bool):
    """Basic UMa path loss of TR 38.901 Table 7.4.1-1 (no shadowing), deterministic form.

    The effective environment height is fixed at h_E = 1 m. The spec draws h_E from
    {1, 12, 15, ...} with probability 1/(1 + C(d2D, h_UT)); C = 0 for h_UT < 13 m, so the
    fixed h_E = 1 m *is* the spec for street-level UEs (the 1.5 m of this toolkit).

    LOS: PL1 = 28 + 22 lg d3D + 20 lg fc for d2D <= d'BP, else
    PL2 = 28 + 40 lg d3D + 20 lg fc - 9 lg(d'BP^2 + (h_BS - h_UT)^2).
    NLOS: max(PL_LOS, 13.54 + 39.08 lg d3D + 20 lg fc - 0.6 (h_UT - 1.5)). fc in GHz.
    Evaluated by :func:`~veriloc_rt.propagation.pathloss_models.tr38901_pathloss_db` on the
    shipped table.

    Validity is 10 m <= d2D <= 5 km, h_BS = 25 m, 1.5 <= h_UT <= 22.5 m; outside it the
    formula is evaluated as is (no clipping, no error) so callers can plot the extrapolation.

    :param d_2d_m: [...] float64, m, horizontal BS-UE distance (>= 0)
    :param h_bs_m, h_ut_m: [...] float64, m, antenna heights (> h_E = 1 m)
    :param fc_hz: float, Hz
    :param los: bool (or [...] bool array broadcastable with d_2d_m)
    :returns: float or [...] float64, dB
    """
    return tr38901_pathloss_db(uma_table()["pathloss"], d_2d_m, h_bs_m, h_ut_m, fc_hz, los)


def uma_los_probability(d_2d_m, h_ut_m) -> np.ndarray:
    """LoS probability of TR 38.901 Table 7.4.2-1, UMa, outdoor UE.

    Pr = 1 for d2D <= 18 m, else [18/d + exp(-d/63)(1 - 18/d)] (1 + C'(h_UT) 5/4 (d/100)^3
    exp(-d/150)), C' = 0 for h_UT <= 13 m and ((h_UT - 13)/10)^1.5 up to 23 m.

    :param d_2d_m: [...] float64, m; h_ut_m: [...] float64, m
    :returns: [...] float64, probability in [0, 1]
    """
    t = uma_table()["los_probability"]
    d = np.asarray(d_2d_m, dtype=float)
    hu = np.asarray(h_ut_m, dtype=float)
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"Argument `d_2d_m` must be finite and >= 0, not {d_2d_m!r}")
    c_prime = np.where(hu <= t["h_ut_threshold_m"], 0.0,
                       (np.clip(hu - t["h_ut_threshold_m"], 0, None) / t["h_ut_scale_m"])
                       ** t["h_ut_exponent"])
    dd = np.maximum(d, t["d_near_m"])
    base = t["d_near_m"] / dd + np.exp(-dd / t["d_decay_m"]) * (1.0 - t["d_near_m"] / dd)
    boost = 1.0 + c_prime * t["gain"] * (dd / t["d_scale_m"]) ** 3 * np.exp(-dd / t["d_exp_m"])
    return np.where(d <= t["d_near_m"], 1.0, np.clip(base * boost, 0.0, 1.0))


def _fc_lsp_ghz(fc_hz: float) -> float:
    """Carrier frequency for the frequency-dependent LSP entries (Table 7.5-6 note 6), GHz."""
    return max(fc_hz / 1e9, uma_table()["lsp"]["fc_min_ghz"])


def lsp_statistics(los: bool, fc_hz: float, d_2d_m, h_ut_m) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the seven LSPs in :data:`LSP_ORDER` (Tables 7.5-6/7.5-7).

    SF and K are in dB; DS, ASD, ASA, ZSD, ZSA in lg units (DS in s, angles in deg). For NLoS
    the K entries are unused zeros (0, 0): K does not exist there.

    :param d_2d_m, h_ut_m: [L] float64, m (ZSD depends on them)
    :returns: (mu, sigma), each [L, 7] float64
    """
    tab = uma_table()
    p = tab["lsp"]["los" if los else "nlos"]
    z = tab["zsd"]["los" if los else "nlos"]
    lf = np.log10(_fc_lsp_ghz(fc_hz))
    d2 = np.atleast_1d(np.asarray(d_2d_m, dtype=float))
    hu = np.broadcast_to(np.asarray(h_ut_m, dtype=float), d2.shape)
    mu_zsd = np.maximum(z["floor"], z["d2d_slope_per_km"] * d2 / 1000.0
                        + z["h_ut_slope"] * (hu - 1.5) + z["const"])
    mu = np.zeros(d2.shape + (7,))
    sd = np.zeros(d2.shape + (7,))
    sd[:, 0] = p["sigma_SF_db"]
    if los:
        mu[:, 1], sd[:, 1] = p["mu_K_db"], p["sigma_K_db"]
    for i, name in ((2, "DS"), (3, "ASD"), (4, "ASA"), (6, "ZSA")):
        a, b = p[f"mu_lg{name}"]
        mu[:, i], sd[:, i] = a + b * lf, p[f"sigma_lg{name}"]
    mu[:, 5], sd[:, 5] = mu_zsd, z["sigma"]
    return mu, sd


def zod_offset_deg(los: bool, fc_hz: float, d_2d_m, h_ut_m) -> np.ndarray:
    """ZOD offset mu_offset,ZOD of Table 7.5-7 (0 for LoS), fc clipped to >= 6 GHz.

    :returns: [L] float64, deg
    """
    d2 = np.atleast_1d(np.asarray(d_2d_m, dtype=float))
    if los:
        return np.zeros_like(d2)
    lf = np.log10(_fc_lsp_ghz(fc_hz))
    hu = np.broadcast_to(np.asarray(h_ut_m, dtype=float), d2.shape)
    expo = ((0.208 * lf - 0.782) * np.log10(np.maximum(25.0, d2)) - 0.13 * lf + 2.03
            - 0.07 * (hu - 1.5))
    return 7.66 * lf - 5.96 - 10.0**expo


def correlation_matrix(los: bool) -> np.ndarray:
    """Cross-correlation matrix of the LSPs in :data:`LSP_ORDER` (Table 7.5-6).

    For NLoS the K row and column are the identity (K is not used).

    :returns: [7, 7] float64, symmetric, unit diagonal
    """
    cc = uma_table()["lsp"]["los" if los else "nlos"]["cross_correlation"]
    c = np.eye(7)
    for key, val in cc.items():
        a, b = key.split("_")
        i, j = LSP_ORDER.index(a), LSP_ORDER.index(b)
        c[i, j] = c[j, i] = val
    return c


def decorrelation_distances_m(los: bool) -> np.ndarray:
    """Decorrelation distances of the LSPs in :data:`LSP_ORDER` (Table 7.5-6).

    :returns: [7] float64, m (K for NLoS: 1 m, unused)
    """
    dd = uma_table()["lsp"]["los" if los else "nlos"]["decorrelation_m"]
    return np.array([float(dd.get(n, 1.0)) for n in LSP_ORDER])


def cluster_parameters(los: bool, fc_hz: float) -> dict:
    """Per-condition fast-fading constants (Tables 7.5-6, 7.5-2, 7.5-4).

    :returns: dict with ``num_clusters``, ``rays_per_cluster``, ``r_tau``, ``zeta_db``,
        ``c_ds_s`` (s), ``c_asd_deg``, ``c_asa_deg``, ``c_zsa_deg``, ``c_phi_nlos``, ``c_theta_nlos``
    """
    tab = uma_table()
    p = tab["lsp"]["los" if los else "nlos"]
    a, b, floor = p["c_ds_ns"]
    c_ds_ns = max(floor, a + b * np.log10(_fc_lsp_ghz(fc_hz)))
    n = int(p["num_clusters"])
    return {
        "num_clusters": n, "rays_per_cluster": int(p["rays_per_cluster"]),
        "r_tau": float(p["r_tau"]), "zeta_db": float(p["zeta_db"]), "c_ds_s": c_ds_ns * 1e-9,
        "c_asd_deg": float(p["c_asd_deg"]), "c_asa_deg": float(p["c_asa_deg"]),
        "c_zsa_deg": float(p["c_zsa_deg"]),
        "c_phi_nlos": float(tab["c_phi_nlos"][str(n)]),
        "c_theta_nlos": float(tab["c_theta_nlos"][str(n)]),
    }
