"""The FBS 'bias' spoofer by geometry alone: what its timing bias does to the fix.

The paper's selective spoofer adds "a specific timing delay" to a targeted BS's PRS and does not
give its value. :func:`biased_fix_outcomes` shows what the value decides without any waveform:
exact RSTDs, the bias added to the spoofed slots' arrivals, the chain's multilaterator (same
residual check); :func:`sweep` counts the outcomes over a config's attack window per bias
(``benchmarks/fbs_bias_sweep.py`` prints them).
"""

from __future__ import annotations

import tempfile

import numpy as np

from ..constants import SPEED_OF_LIGHT
from ..detectors.outcomes import OUTCOMES, outcome_of
from ..phy.receiver.multilateration import Multilaterator
from ..world.geometry import build_geometry

__all__ = ["biased_fix_outcomes", "sweep"]


def biased_fix_outcomes(bs_pos, ue_pos, bias_s: float, slots, success_threshold_m: float,
                        max_residual_m: float = 10.0) -> list[str]:
    """What mode 'bias' does to the fix by geometry alone: exact RSTDs, ``bias_s`` added to the
    ``slots``' arrivals, the chain's multilaterator (same residual check).

    :param bs_pos: [P, B, 3] float64, m, serving BSs per point (slot 0 the RSTD reference)
    :param ue_pos: [P, 3] float64, m
    :return: per point 'success' (fix within ``success_threshold_m``), 'large_error' or
        'service_failure' (no fix), the run's outcome labels
    """
    b = np.asarray(bs_pos, dtype=np.float64)
    u = np.asarray(ue_pos, dtype=np.float64)
    if b.ndim != 3 or u.shape != (b.shape[0], 3):
        raise ValueError(f"Arguments `bs_pos` [P, B, 3] and `ue_pos` [P, 3] do not match: "
                         f"{b.shape}, {u.shape}")
    out = []
    for bs, ue in zip(b, u):
        toa = np.linalg.norm(bs - ue, axis=1) / SPEED_OF_LIGHT
        toa[list(slots)] += bias_s
        fix = Multilaterator(ue_height_m=float(ue[2]), max_residual_m=max_residual_m)(bs, toa - toa[0], 0)
        out.append(outcome_of(fix.ok, float(np.linalg.norm(fix.position[:2] - ue[:2])),
                              success_threshold_m))
    return out


def sweep(cfg, biases_m, slots) -> list[tuple[float, float, float, float]]:
    """(bias in m, success %, large error %, service failure %) per bias over the attack window."""
    with tempfile.TemporaryDirectory() as tmp:
        geo = build_geometry(cfg, tmp)
    window = np.flatnonzero(cfg.run.attack_points(geo.num_points))
    bs = geo.bs_pos[geo.serving[window]]
    out = []
    for bias in biases_m:
        got = biased_fix_outcomes(bs, geo.ue.pos[window], bias / SPEED_OF_LIGHT, slots,
                                  cfg.run.success_threshold_m, cfg.receiver.max_residual_m)
        n = max(len(got), 1)
        out.append((bias, *(100.0 * got.count(k) / n
                            for k in OUTCOMES)))
    return out
