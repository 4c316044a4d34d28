"""The same links as :func:`~veriloc_rt.propagation.raytrace.trace`, drawn from TR 38.901 UMa.

The serving BS -> UE and BS -> adversary links are UMa links (25 m BS, 1.5 m UE). The
adversary -> UE link is a street-level link for which UMa has no table; it is drawn with the UMa
formulas all the same (as the MATLAB-era simulators did), so treat its statistics as indicative.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..config import PropagationConfig
from ..constants import SPEED_OF_LIGHT
from ..rng import stream
from .cir import ADVERSARY_TX, NO_TX, ula_element_positions
from .raytrace import Propagation
from .uma import uma_cir


def uma_propagation(geometry, cfg: PropagationConfig, seed: int,
                    adversary_points: np.ndarray | None = None) -> Propagation:
    """Draw every link of ``geometry`` from the stochastic UMa model (``cfg.uma_mode``).

    Each link family has its own random stream derived from ``seed``.
    """
    t0 = time.perf_counter()
    ue, adv, serving, bs_pos = geometry.ue, geometry.adversary, geometry.serving, geometry.bs_pos
    P = ue.num_points
    fc = cfg.carrier_frequency_hz
    lam = SPEED_OF_LIGHT / fc
    arr = cfg.ue_array
    elem = ula_element_positions(arr.num_elements, arr.spacing_wavelengths * lam,
                                 np.deg2rad(arr.axis_azimuth_deg))
    active = np.ones(P, bool) if adversary_points is None else np.asarray(adversary_points, bool)
    bs_tx = bs_pos[serving]                       # [P, num_trps, 3]
    zeros = np.zeros(bs_tx.shape)
    mode = cfg.uma_mode
    bs_ue = uma_cir(bs_tx, ue.pos, ue.vel, zeros, serving, fc, elem,
                    stream(seed, "uma", 0), mode)
    adv_slots = np.where(active[:, None], serving, NO_TX)
    bs_adv = uma_cir(bs_tx, adv.pos, adv.vel, zeros, adv_slots, fc, np.zeros((1, 3)),
                     stream(seed, "uma", 1), mode)
    adv_idx = np.where(active, 0, NO_TX)[:, None]
    adv_ue = uma_cir(adv.pos[:, None, :], ue.pos, ue.vel, adv.vel[:, None, :], adv_idx, fc, elem,
                     stream(seed, "uma", 2), mode)
    adv_ue = dataclasses.replace(adv_ue, tx_index=np.where(active, ADVERSARY_TX, NO_TX)[:, None])
    stats = {"model": f"uma/{mode}", "wall_s": time.perf_counter() - t0, "calls": 0,
             "cache_hits": 0, "trace_s": 0.0, "links": int(serving.shape[1] * P + (serving.shape[1] + 1) * active.sum())}
    return Propagation(bs_ue=bs_ue, bs_adv=bs_adv, adv_ue=adv_ue, stats=stats)
