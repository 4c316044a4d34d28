"""The same links as :func:`~veriloc_rt.propagation.raytrace.trace`, drawn from TR 38.901 UMa or
UMi - Street Canyon (``propagation.model``).

The serving BS -> UE and BS -> adversary links are links of the chosen scenario (UMa: rooftop BS
at 25 m; UMi: street-level BS at 10 m; UE 1.5 m). The adversary -> UE link is a street-level link
at both ends for which neither table is made (TR 38.901 has no UE-to-UE scenario); it is drawn
with the same scenario's formulas all the same (as the MATLAB-era simulators did), so treat its
statistics as indicative.

``propagation.stochastic_pathloss_offset_los_db`` / ``..._nlos_db`` add a per-LoS-state constant
to the serving links' path loss (the draws do not change): ``veriloc-rt compare
--match-pathloss`` sets them so that the stochastic arm's median path loss equals the traced one.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..config import PropagationConfig
from ..constants import SPEED_OF_LIGHT
from ..rng import stream
from .cir import ADVERSARY_TX, NO_TX, CIR, ula_element_positions
from .raytrace import Propagation
from .tr38901 import SCENARIOS
from .uma import uma_cir

__all__ = ["stochastic_propagation", "uma_propagation", "STOCHASTIC_MODELS", "offset_pathloss"]

#: ``propagation.model`` values drawn by :func:`stochastic_propagation`
STOCHASTIC_MODELS = SCENARIOS


def offset_pathloss(cir: CIR, offset_db: dict | None) -> CIR:
    """``cir`` with ``offset_db["los"]`` / ``["nlos"]`` dB added to the path loss of its LoS /
    NLoS links (gains scaled by 10^(-offset/20)); ``None`` returns ``cir`` itself."""
    if not offset_db:
        return cir
    off = np.where(cir.los, float(offset_db.get("los", 0.0)), float(offset_db.get("nlos", 0.0)))
    scale = 10.0 ** (-off / 20.0)
    return dataclasses.replace(cir, gains=cir.gains * scale[:, :, None, None],
                               meta={**cir.meta, "pathloss_offset_db": dict(offset_db)})


def stochastic_propagation(geometry, cfg: PropagationConfig, seed: int,
                           adversary_points: np.ndarray | None = None) -> Propagation:
    """Draw every link of ``geometry`` from the stochastic model ``cfg.model`` ("uma" or "umi",
    mode ``cfg.uma_mode``).

    Each link family has its own random stream derived from ``seed`` and the model's name, so
    UMa and UMi draws are independent and each is the same whatever the other does.

    The config's ``stochastic_pathloss_offset_los_db`` / ``..._nlos_db`` are added to the
    serving (BS -> UE) links' path loss (:func:`offset_pathloss`); the adversary's links are
    left as drawn.
    """
    model = cfg.model if cfg.model in STOCHASTIC_MODELS else "uma"
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
                    stream(seed, model, 0), mode, scenario=model)
    adv_slots = np.where(active[:, None], serving, NO_TX)
    bs_adv = uma_cir(bs_tx, adv.pos, adv.vel, zeros, adv_slots, fc, np.zeros((1, 3)),
                     stream(seed, model, 1), mode, scenario=model)
    adv_idx = np.where(active, 0, NO_TX)[:, None]
    adv_ue = uma_cir(adv.pos[:, None, :], ue.pos, ue.vel, adv.vel[:, None, :], adv_idx, fc, elem,
                     stream(seed, model, 2), mode, scenario=model)
    adv_ue = dataclasses.replace(adv_ue, tx_index=np.where(active, ADVERSARY_TX, NO_TX)[:, None])
    offset = {"los": cfg.stochastic_pathloss_offset_los_db,
              "nlos": cfg.stochastic_pathloss_offset_nlos_db}
    if any(offset.values()):
        bs_ue = offset_pathloss(bs_ue, offset)
    n_trps = serving.shape[1]
    stats = {"model": f"{model}/{mode}", "wall_s": time.perf_counter() - t0, "calls": 0,
             "cache_hits": 0, "trace_s": 0.0,
             "links": int(n_trps * P + (n_trps + 1) * active.sum())}
    return Propagation(bs_ue=bs_ue, bs_adv=bs_adv, adv_ue=adv_ue, stats=stats)


def uma_propagation(geometry, cfg: PropagationConfig, seed: int,
                    adversary_points: np.ndarray | None = None) -> Propagation:
    """:func:`stochastic_propagation` (kept name: it draws UMa, or UMi when ``cfg.model`` is
    "umi")."""
    return stochastic_propagation(geometry, cfg, seed, adversary_points)
