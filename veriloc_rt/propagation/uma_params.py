"""TR 38.901 UMa closed-form parameters: path loss, LoS probability and LSP statistics.

All numbers come from ``veriloc_rt/data/uma_tr38901_v18.json`` (TR 38.901 V18.0.0, identical in
V14.1.0 to V18.x; pinned pre-Release-19), evaluated by the scenario-generic
:mod:`veriloc_rt.propagation.tr38901` (this module fixes the scenario to UMa); the random draws
live in :mod:`veriloc_rt.propagation.uma_lsp` and :mod:`veriloc_rt.propagation.uma_clusters`.

Conventions: distances in m, ``fc_hz`` in Hz (converted to GHz inside, as the tables use),
``lg`` = log10 with the delay spread in s and the angle spreads in degrees (the tables' units).
"""

from __future__ import annotations

import numpy as np

from . import tr38901
from .pathloss_models import breakpoint_distance, tr38901_pathloss_db  # noqa: F401 (re-export)
from .tr38901 import LSP_ORDER  # noqa: F401 (re-export)

#: The TR 38.901 version the shipped tables are pinned to
TR38901_VERSION = tr38901.TR38901_VERSIONS["uma"]


def uma_table() -> dict:
    """The shipped UMa table (parsed JSON, cached; treat as read-only)."""
    return tr38901.scenario_table("uma")


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
    return tr38901.pathloss_db("uma", d_2d_m, h_bs_m, h_ut_m, fc_hz, los)


def uma_los_probability(d_2d_m, h_ut_m) -> np.ndarray:
    """LoS probability of TR 38.901 Table 7.4.2-1, UMa, outdoor UE.

    Pr = 1 for d2D <= 18 m, else [18/d + exp(-d/63)(1 - 18/d)] (1 + C'(h_UT) 5/4 (d/100)^3
    exp(-d/150)), C' = 0 for h_UT <= 13 m and ((h_UT - 13)/10)^1.5 up to 23 m.

    :param d_2d_m: [...] float64, m; h_ut_m: [...] float64, m
    :returns: [...] float64, probability in [0, 1]
    """
    return tr38901.los_probability("uma", d_2d_m, h_ut_m)


def lsp_statistics(los: bool, fc_hz: float, d_2d_m, h_ut_m) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the seven UMa LSPs in :data:`LSP_ORDER` (Tables
    7.5-6/7.5-7); see :func:`veriloc_rt.propagation.tr38901.lsp_statistics`.

    :param d_2d_m, h_ut_m: [L] float64, m (ZSD depends on them)
    :returns: (mu, sigma), each [L, 7] float64
    """
    return tr38901.lsp_statistics("uma", los, fc_hz, d_2d_m, h_ut_m)


def zod_offset_deg(los: bool, fc_hz: float, d_2d_m, h_ut_m) -> np.ndarray:
    """ZOD offset mu_offset,ZOD of Table 7.5-7 (0 for LoS), fc clipped to >= 6 GHz.

    :returns: [L] float64, deg
    """
    return tr38901.zod_offset_deg("uma", los, fc_hz, d_2d_m, h_ut_m)


def correlation_matrix(los: bool) -> np.ndarray:
    """Cross-correlation matrix of the UMa LSPs in :data:`LSP_ORDER` (Table 7.5-6).

    :returns: [7, 7] float64, symmetric, unit diagonal
    """
    return tr38901.correlation_matrix("uma", los)


def decorrelation_distances_m(los: bool) -> np.ndarray:
    """Decorrelation distances of the UMa LSPs in :data:`LSP_ORDER` (Table 7.5-6), m."""
    return tr38901.decorrelation_distances_m("uma", los)


def cluster_parameters(los: bool, fc_hz: float) -> dict:
    """Per-condition UMa fast-fading constants (Tables 7.5-6, 7.5-2, 7.5-4); see
    :func:`veriloc_rt.propagation.tr38901.cluster_parameters`."""
    return tr38901.cluster_parameters("uma", los, fc_hz)
