"""Stochastic TR 38.901 UMi - Street Canyon channel: the UMa procedure on the UMi table.

Street-level small cells (TR 38.901 Table 7.2-1: h_BS = 10 m, below the surrounding rooftops,
ISD 200 m). :func:`umi_cir` is :func:`veriloc_rt.propagation.uma.uma_cir` with
``scenario="umi"``: the same LoS-state, LSP, cluster and ray draws (7.5 steps 2-11), the same
:class:`~veriloc_rt.propagation.cir.CIR`, the same antennas (isotropic, single vertical
polarisation), with the UMi-SC numbers of ``veriloc_rt/data/umi_tr38901_v18.json``:

* path loss, Table 7.4.1-1 (UMi - Street Canyon; LoS dual slope, NLoS
  max(PL_LOS, 22.4 + 35.3 lg d3D + 21.3 lg fc - 0.3 (h_UT - 1.5))), shadow fading 4 / 7.82 dB;
* LoS probability, Table 7.4.2-1: 18/d + exp(-d/36)(1 - 18/d) beyond 18 m;
* LSPs, Table 7.5-6 Part-1 UMi column (frequency entries in lg(1 + fc), fc clipped at 2 GHz),
  ZSD and ZOD offset of Table 7.5-8, cluster counts 12 (LoS) / 19 (NLoS), 20 rays, r_tau 3 / 2.1,
  c_DS 5 / 11 ns, c_ASD 3 / 10 deg, c_ASA 17 / 22 deg, c_ZSA 7 deg, zeta 3 dB, XPR 9 / 8 dB
  (tabled; not drawn: single polarisation, as UMa), C_phi / C_theta of Tables 7.5-2 / 7.5-4 for
  12 and 19 clusters.

Pinned to TR 38.901 V18.0.0, the UMa table's version (pre-Release-19; the UMi rows are the
same from V15.0.0 to V18.x).
"""

from __future__ import annotations

import numpy as np

from . import tr38901
from .pathloss_models import umi_pathloss_db
from .uma import uma_cir

__all__ = ["umi_cir", "umi_pathloss_db", "umi_los_probability", "UMI_TR38901_VERSION"]

#: The TR 38.901 version the shipped UMi table is pinned to
UMI_TR38901_VERSION = tr38901.TR38901_VERSIONS["umi"]


def umi_los_probability(d_2d_m, h_ut_m) -> np.ndarray:
    """LoS probability of TR 38.901 Table 7.4.2-1, UMi - Street Canyon, outdoor UE.

    Pr = 1 for d2D <= 18 m, else 18/d + exp(-d/36)(1 - 18/d) (no h_UT dependence).

    :param d_2d_m: [...] float64, m; h_ut_m: [...] float64, m (unused by the formula)
    :returns: [...] float64, probability in [0, 1]
    """
    return tr38901.los_probability("umi", d_2d_m, h_ut_m)


def umi_cir(tx_pos, rx_pos, rx_vel, tx_vel, tx_index, fc_hz: float, element_pos,
            rng: np.random.Generator, mode: str = "fast_fading", **kwargs):
    """Channel impulse responses of TR 38.901 UMi - Street Canyon; arguments and returns as
    :func:`veriloc_rt.propagation.uma.uma_cir` (keywords ``spatial_consistency``,
    ``los_state``, ``return_parameters``)."""
    return uma_cir(tx_pos, rx_pos, rx_vel, tx_vel, tx_index, fc_hz, element_pos, rng, mode,
                   scenario="umi", **kwargs)
