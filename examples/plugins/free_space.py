"""Example plug-in propagation model: free space (docs/extending.md, "A new propagation model").

One direct path per link whose power gain is Friis's, (lambda / (4 pi d))^2 with d the 3-D
distance (isotropic antennas at both ends). The path geometry (delays, angles, Doppler, the
UE array's phases) comes from the stochastic model's one-path mode
(``propagation.uma_mode`` 'pathloss_only'); only each path's amplitude is set to Friis's.
Register it by importing this module, then set ``propagation.model`` to ``"free_space"``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.propagation.cir import CIR
from veriloc_rt.propagation.models import PROPAGATION_REGISTRY, PropagationModel
from veriloc_rt.propagation.stochastic import stochastic_propagation


def friis(cir: CIR) -> CIR:
    """``cir`` (one path per link) with each path's amplitude lambda / (4 pi d)."""
    lam = SPEED_OF_LIGHT / cir.carrier_frequency
    d = np.linalg.norm(cir.tx_pos - cir.rx_pos[:, None, :], axis=-1)     # [points, tx]
    amp = lam / (4.0 * np.pi * np.maximum(d, 1e-3))
    mag = np.abs(cir.gains)
    unit = np.divide(cir.gains, mag, out=np.zeros_like(cir.gains), where=mag > 0)
    gains = np.where(cir.valid[:, :, None, :], unit * amp[:, :, None, None], 0.0)
    return dataclasses.replace(cir, gains=gains, los=cir.los | cir.valid.any(axis=-1),
                               meta={**cir.meta, "model": "free_space"})


@PROPAGATION_REGISTRY.register("free_space")
class FreeSpace(PropagationModel):
    """Every link a single Friis path."""

    def __call__(self, geometry, cfg, seed, *, progress=None, cache_dir="default",
                 adversary_points=None, workers=1):
        one_path = dataclasses.replace(cfg, model="uma", uma_mode="pathloss_only",
                                       stochastic_pathloss_offset_los_db=0.0,
                                       stochastic_pathloss_offset_nlos_db=0.0)
        p = stochastic_propagation(geometry, one_path, seed)
        return dataclasses.replace(p, bs_ue=friis(p.bs_ue), bs_adv=friis(p.bs_adv),
                                   adv_ue=friis(p.adv_ue))
