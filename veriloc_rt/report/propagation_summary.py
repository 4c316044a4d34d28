"""Channel statistics of a set of CIRs (what the traced scene looks like to a receiver)."""

from __future__ import annotations

import numpy as np

from ..constants import SPEED_OF_LIGHT

from ..propagation.cir import CIR, INTERACTION_DIFFRACTION, INTERACTION_NONE


def rms_delay_spread(cir: CIR) -> np.ndarray:
    """Power-weighted rms delay spread per link (NaN where there is no path).

    :returns: [num_points, num_tx] float64, s
    """
    p = cir.path_power()
    tot = p.sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (p * np.where(cir.valid, cir.delays, 0.0)).sum(-1) / tot
        var = (p * (np.where(cir.valid, cir.delays, 0.0) - mean[..., None]) ** 2).sum(-1) / tot
    return np.where(tot > 0, np.sqrt(np.maximum(var, 0.0)), np.nan)


def summarize(cir: CIR) -> dict:
    """Coverage, LoS share, paths per link, delay spread and first-path excess delay (shares
    as fractions in [0, 1]).

    Only links that exist (``tx_index`` set) count.
    """
    used = cir.tx_index != -1
    has = cir.has_path() & used
    n_used = int(used.sum())
    out = {"links": n_used,
           "links_with_path_share": float(has.sum()) / max(n_used, 1)}
    if not has.any():
        return out
    paths = cir.valid.sum(-1)[has]
    ds = rms_delay_spread(cir)[has]
    excess = (cir.first_path_delay() - cir.geometric_delay())[has]
    only_diffracted = np.all((cir.interactions == INTERACTION_NONE)
                             | (cir.interactions == INTERACTION_DIFFRACTION), axis=-1)
    out.update({
        "los_share": float(cir.los[has].mean()),
        "paths_per_link_mean": float(paths.mean()),
        "delay_spread_ns_p50": float(np.nanpercentile(ds, 50) * 1e9),
        "delay_spread_ns_p95": float(np.nanpercentile(ds, 95) * 1e9),
        "first_path_excess_m_p50": float(np.percentile(excess, 50) * SPEED_OF_LIGHT),
        "first_path_excess_m_p95": float(np.percentile(excess, 95) * SPEED_OF_LIGHT),
        "diffraction_path_share": float(
            (cir.valid & np.any(cir.interactions == INTERACTION_DIFFRACTION, -1)
             & only_diffracted)[has].sum() / max(paths.sum(), 1)),
    })
    return out
