"""Stochastic TR 38.901 UMa (and UMi-SC) channel producing the toolkit's
:class:`~veriloc_rt.propagation.cir.CIR`.

``scenario`` picks the table (:mod:`veriloc_rt.propagation.tr38901`): "uma" (default) or "umi"
(:func:`veriloc_rt.propagation.umi.umi_cir`); the procedure below is the same for both.

Two modes:

* ``"fast_fading"``: the full 7.5 procedure (LoS state, path loss, spatially consistent LSPs,
  clusters, rays, sub-clusters, K-factor, direct ray). Every ray is one CIR path; its gain at
  UE element ``a`` is ``10^(-(PL+SF)/20) sqrt(P_ray) exp(j Phi) exp(j 2 pi r_a.u / lambda)``
  (:func:`~veriloc_rt.propagation.cir.array_response`). A LoS link has
  ``N M + 1`` paths (the direct ray last before sorting), an NLoS link ``N M``; paths are sorted
  by delay and padded with ``valid = False``. Absolute delay = d3D / c + the ray's excess delay;
  the first NLoS cluster therefore arrives at d3D / c (the optional 7.6.9 absolute-ToA excess
  delay is not modelled).
* ``"pathloss_only"``: one direct path per link at the geometric delay and angles, amplitude
  ``10^(-(PL+SF)/20)``, zero phase: what MATLAB-era system simulators used.

Antennas: isotropic, single (vertical) polarisation at both ends, so the polarisation matrix
of (7.5-28) reduces to ``exp(j Phi_theta_theta)`` and XPR plays no role. The carrier phase
``exp(-j 2 pi fc tau)`` is *not* in the gains (CIR convention); the direct ray's gain is real.

Reference: 3GPP TR 38.901 V18.0.0 (pre-Rel-19 UMa, identical since V14.1.0), clauses 7.4.1,
7.4.2, 7.5; tables in ``veriloc_rt/data/uma_tr38901_v18.json``.
"""

from __future__ import annotations

import numpy as np

from ..constants import SPEED_OF_LIGHT
from .cir import CIR, array_response, doppler_shift
from .uma_clusters import generate_rays
from .uma_lsp import UmaLinkParameters, draw_link_parameters
from .tr38901 import SCENARIO_NAMES, SCENARIOS, TR38901_VERSIONS
from .uma_params import TR38901_VERSION, uma_los_probability, uma_pathloss_db

__all__ = ["uma_cir", "uma_pathloss_db", "uma_los_probability", "UmaLinkParameters",
           "TR38901_VERSION", "MODES"]

#: Supported channel modes
MODES = ("fast_fading", "pathloss_only")

_PATH_KEYS = ("delay", "power", "aoa_az", "aoa_zen", "aod_az", "aod_zen", "phase", "valid")


def _as_array(name: str, value, shape_tail: tuple, ndim: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim != ndim or arr.shape[ndim - len(shape_tail):] != shape_tail:
        raise ValueError(f"Argument `{name}` must have shape [..., {', '.join(map(str, shape_tail))}]"
                         f" with {ndim} axes, not {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"Argument `{name}` must be finite")
    return arr


def _direction(frm: np.ndarray, to: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and zenith of the direction frm -> to, rad."""
    d = to - frm
    az = np.arctan2(d[..., 1], d[..., 0])
    zen = np.arccos(np.clip(d[..., 2] / np.linalg.norm(d, axis=-1), -1.0, 1.0))
    return az, zen


def uma_cir(tx_pos, rx_pos, rx_vel, tx_vel, tx_index, fc_hz: float, element_pos,
            rng: np.random.Generator, mode: str = "fast_fading", *,
            spatial_consistency: bool = True, los_state=None,
            return_parameters: bool = False, scenario: str = "uma"):
    """Channel impulse responses of TR 38.901 UMa (or UMi) for every link slot and point.

    Heights are z coordinates (ground at z = 0): the BS height ``tx_pos[..., 2]`` and the UE
    height ``rx_pos[:, 2]`` enter the path loss, LoS probability and ZSD tables.

    :param tx_pos: [num_points, num_tx, 3] float64, m (ignored in slots with tx_index -1)
    :param rx_pos: [num_points, 3] float64, m, the UE array centre (consecutive points form the
        trajectory used for spatial consistency)
    :param rx_vel: [num_points, 3] float64, m/s
    :param tx_vel: [num_points, num_tx, 3] float64, m/s
    :param tx_index: [num_points, num_tx] int64, transmitter id (-1: empty slot)
    :param fc_hz: float, Hz, carrier frequency
    :param element_pos: [num_ant, 3] float64, m, UE element offsets (e.g. ``ula_element_positions``)
    :param rng: numpy ``Generator``; the output is a deterministic function of its state
    :param mode: ``"fast_fading"`` or ``"pathloss_only"``
    :param spatial_consistency: correlate LoS state and LSPs along the trajectory
    :param los_state: optional [num_points, num_tx] bool, forces LoS/NLoS instead of drawing it
    :param return_parameters: also return the drawn :class:`UmaLinkParameters`
    :param scenario: "uma" or "umi", the TR 38.901 table
    :returns: :class:`CIR` (and :class:`UmaLinkParameters` if ``return_parameters``)
    """
    if scenario not in SCENARIOS:
        raise ValueError(f"Argument `scenario` must be one of {SCENARIOS}, not {scenario!r}")
    if mode not in MODES:
        raise ValueError(f"Argument `mode` must be one of {MODES}, not {mode!r}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
    if not np.isfinite(fc_hz) or fc_hz <= 0:
        raise ValueError(f"Argument `fc_hz` must be finite and > 0, not {fc_hz!r}")
    tx_index = np.asarray(tx_index)
    if tx_index.ndim != 2 or not np.issubdtype(tx_index.dtype, np.integer):
        raise ValueError(f"Argument `tx_index` must be a 2-D integer array, not {tx_index.dtype} "
                         f"{tx_index.shape}")
    p, t = tx_index.shape
    ok = tx_index >= 0
    tx_raw = np.asarray(tx_pos, dtype=float)
    if tx_raw.shape != (p, t, 3):
        raise ValueError(f"Argument `tx_pos` must have shape {(p, t, 3)}, not {tx_raw.shape}")
    rx_pos = _as_array("rx_pos", rx_pos, (3,), 2)
    if rx_pos.shape[0] != p:
        raise ValueError(f"Argument `rx_pos` must have shape {(p, 3)}, not {rx_pos.shape}")
    rx_vel = _as_array("rx_vel", rx_vel, (3,), 2)
    tx_vel = np.nan_to_num(np.asarray(tx_vel, dtype=float))
    if rx_vel.shape != (p, 3) or tx_vel.shape != (p, t, 3):
        raise ValueError(f"Arguments `rx_vel`, `tx_vel` must have shapes {(p, 3)}, {(p, t, 3)}, "
                         f"not {rx_vel.shape}, {tx_vel.shape}")
    element_pos = _as_array("element_pos", element_pos, (3,), 2)
    if not np.all(np.isfinite(tx_raw[ok])):
        raise ValueError("Argument `tx_pos` must be finite in every slot with tx_index >= 0")
    # empty slots: harmless stand-in geometry, masked at the end
    stand_in = rx_pos[:, None, :] + np.array([100.0, 0.0, 23.5])
    tx = np.where(ok[..., None], tx_raw, stand_in)
    if np.any(tx[..., 2] <= 1.0) or np.any(rx_pos[:, 2] <= 1.0):
        raise ValueError("Arguments `tx_pos`, `rx_pos`: antenna heights (z) must be > 1 m "
                         "(h_E of Table 7.4.1-1)")

    wavelength = SPEED_OF_LIGHT / fc_hz
    par = draw_link_parameters(tx, rx_pos, tx_index, fc_hz, rng,
                               spatial_consistency=spatial_consistency, los_state=los_state,
                               scenario=scenario)
    aoa_az, aoa_zen = _direction(rx_pos[:, None, :], tx)
    aod_az, aod_zen = _direction(tx, rx_pos[:, None, :])
    d3 = np.linalg.norm(tx - rx_pos[:, None, :], axis=-1)

    if mode == "pathloss_only":
        paths = {"delay": np.zeros((p, t, 1)), "power": np.ones((p, t, 1)),
                 "aoa_az": aoa_az[..., None], "aoa_zen": aoa_zen[..., None],
                 "aod_az": aod_az[..., None], "aod_zen": aod_zen[..., None],
                 "phase": np.zeros((p, t, 1)), "valid": np.ones((p, t, 1), dtype=bool)}
    else:
        paths = _fast_fading_paths(par, fc_hz, ok, aoa_az, aoa_zen, aod_az, aod_zen, rng,
                                   scenario)

    valid = paths["valid"] & ok[..., None]
    amp = 10.0 ** (-(par.pathloss_db + par.sf_db) / 20.0)
    delays = np.where(valid, d3[..., None] / SPEED_OF_LIGHT + paths["delay"], 0.0)
    angles = {k: np.where(valid, paths[k], 0.0) for k in ("aoa_az", "aoa_zen", "aod_az", "aod_zen")}
    coef = np.where(valid, amp[..., None] * np.sqrt(paths["power"]) * np.exp(1j * paths["phase"]), 0)
    gains = coef[:, :, None, :] * array_response(angles["aoa_az"], angles["aoa_zen"], element_pos,
                                                 wavelength)
    doppler = np.where(valid, doppler_shift(angles["aoa_az"], angles["aoa_zen"], angles["aod_az"],
                                            angles["aod_zen"], rx_vel, tx_vel, wavelength), 0.0)
    n = delays.shape[-1]
    cir = CIR(delays=delays, gains=gains, **angles, doppler=doppler,
              interactions=np.zeros((p, t, n, 1), dtype=np.uint8), valid=valid,
              tx_index=tx_index.astype(np.int64), tx_pos=tx, rx_pos=rx_pos, los=par.los & ok,
              carrier_frequency=float(fc_hz),
              meta={"model": f"3GPP TR 38.901 {SCENARIO_NAMES[scenario]}",
                    "tr38901_version": TR38901_VERSIONS[scenario],
                    "mode": mode, "spatial_consistency": bool(spatial_consistency),
                    "antennas": "isotropic, single vertical polarisation"})
    return (cir, par) if return_parameters else cir


def _fast_fading_paths(par: UmaLinkParameters, fc_hz: float, ok: np.ndarray,
                       aoa_az, aoa_zen, aod_az, aod_zen, rng,
                       scenario: str) -> dict[str, np.ndarray]:
    """Rays of all links, scattered into [P, T, R] arrays sorted by delay (invalid last)."""
    p, t = ok.shape
    groups = []
    for cond in (True, False):
        sel = ok & (par.los == cond)
        if not sel.any():
            continue
        rays = generate_rays(cond, fc_hz, par.ds[sel], par.asd[sel], par.asa[sel], par.zsd[sel],
                             par.zsa[sel], np.nan_to_num(par.k_db[sel]), par.mu_lg_zsd[sel],
                             par.zod_offset[sel], aoa_az[sel], aoa_zen[sel], aod_az[sel],
                             aod_zen[sel], rng, scenario)
        groups.append((sel, rays))
    r = max((g[1]["delay"].shape[1] for g in groups), default=1)
    out = {k: np.zeros((p, t, r), dtype=bool if k == "valid" else float) for k in _PATH_KEYS}
    for sel, rays in groups:
        width = rays["delay"].shape[1]
        for k in _PATH_KEYS:
            out[k][sel, :width] = rays[k]
    order = np.argsort(np.where(out["valid"], out["delay"], np.inf), axis=-1, kind="stable")
    return {k: np.take_along_axis(v, order, axis=-1) for k, v in out.items()}
