"""TR 38.901 UMa / UMi-SC link state and large-scale parameters (7.5 steps 2 and 4), spatially
consistent.

One procedure for both scenarios: ``scenario`` ("uma", "umi") picks the table
(:mod:`veriloc_rt.propagation.tr38901`); the draws and their order are the same.

The seven LSPs (SF, K, DS, ASD, ASA, ZSD, ZSA) of a link are jointly Gaussian in the log
domain with the Table 7.5-6 means, deviations and cross-correlations. With
``spatial_consistency=True`` each LSP's standard-normal innovation is an Ornstein-Uhlenbeck
process in the UE's travelled distance, so two trajectory points ``s`` metres apart along the
path have correlation exp(-s / d_corr) with the Table 7.5-6 decorrelation distance d_corr
(the exponential model of 7.5 step 4 / 7.6.3.1, evaluated along the path rather than on a 2-D
grid). The cross-correlation is applied afterwards with the Cholesky factor of the table's
matrix, as WINNER/QuaDRiGa do. Processes are kept per transmitter id (``tx_index``), so a BS
that leaves and re-enters the serving set keeps consistent LSPs; LoS and NLoS links use
independent processes (the spec draws them separately).

The LoS state is the comparison of a uniform variate with Table 7.4.2-1's probability; with
spatial consistency the uniform is the normal CDF of a 50 m OU process (UMa LOS-state
correlation distance of Table 7.6.3.1-2, [unverified: from memory]; UMi uses the same 50 m,
equally unverified: see the tables' ``los_state_decorrelation_m``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from . import tr38901


@dataclass(frozen=True, eq=False)
class UmaLinkParameters:
    """Per-link state and large-scale parameters drawn for a UMa or UMi channel.

    los : [num_points, num_tx] bool
    sf_db : [num_points, num_tx] float64, dB, shadow fading (added to the path loss)
    k_db : [num_points, num_tx] float64, dB, Ricean K-factor (NaN on NLoS links)
    ds : [num_points, num_tx] float64, s, rms delay spread
    asd, asa, zsd, zsa : [num_points, num_tx] float64, deg, rms angle spreads (clipped)
    mu_lg_zsd : [num_points, num_tx] float64, lg(deg), ZSD log-mean (ZOD ray spread 3/8 10^mu)
    zod_offset : [num_points, num_tx] float64, deg, Table 7.5-7 (UMa) / 7.5-8 (UMi) ZOD offset
    pathloss_db : [num_points, num_tx] float64, dB, Table 7.4.1-1 basic path loss
    d_2d : [num_points, num_tx] float64, m
    """

    los: np.ndarray
    sf_db: np.ndarray
    k_db: np.ndarray
    ds: np.ndarray
    asd: np.ndarray
    asa: np.ndarray
    zsd: np.ndarray
    zsa: np.ndarray
    mu_lg_zsd: np.ndarray
    zod_offset: np.ndarray
    pathloss_db: np.ndarray
    d_2d: np.ndarray


def _ou_innovations(rx_pos: np.ndarray, corr_dist_m: np.ndarray, num_proc: int,
                    rng: np.random.Generator, spatial: bool) -> np.ndarray:
    """Standard-normal processes along the trajectory.

    :param rx_pos: [num_points, 3] float64, m
    :param corr_dist_m: [num_comp] float64, m
    :returns: [num_points, num_proc, num_comp] float64, each marginal N(0, 1)
    """
    p = rx_pos.shape[0]
    w = rng.standard_normal((p, num_proc, corr_dist_m.size))
    if not spatial or p < 2:
        return w
    step = np.linalg.norm(np.diff(rx_pos, axis=0), axis=-1)          # [P-1]
    rho = np.exp(-step[:, None] / corr_dist_m[None, :])              # [P-1, C]
    innov = np.sqrt(1.0 - rho**2)
    out = np.empty_like(w)
    out[0] = w[0]
    for k in range(1, p):
        out[k] = rho[k - 1] * out[k - 1] + innov[k - 1] * w[k]
    return out


def draw_link_parameters(tx_pos: np.ndarray, rx_pos: np.ndarray, tx_index: np.ndarray,
                         fc_hz: float, rng: np.random.Generator, *,
                         spatial_consistency: bool = True,
                         los_state: np.ndarray | None = None,
                         scenario: str = "uma") -> UmaLinkParameters:
    """Draw LoS states, path loss and correlated LSPs for every link slot (7.5 steps 2-4).

    Heights are the z coordinates (ground at z = 0). Slots with ``tx_index < 0`` get values
    computed for a stand-in geometry; callers mask them.

    :param tx_pos: [num_points, num_tx, 3] float64, m
    :param rx_pos: [num_points, 3] float64, m
    :param tx_index: [num_points, num_tx] int64, transmitter id (-1: empty slot)
    :param fc_hz: float, Hz
    :param rng: numpy Generator (the only source of randomness)
    :param spatial_consistency: OU-correlate LSPs and LoS state along the trajectory
    :param los_state: optional [num_points, num_tx] bool, forces the LoS state (no draw)
    :param scenario: "uma" or "umi" (the TR 38.901 table)
    """
    tab = tr38901.scenario_table(scenario)
    p, t = tx_index.shape
    d_2d = np.linalg.norm(tx_pos[..., :2] - rx_pos[:, None, :2], axis=-1)
    h_bs = tx_pos[..., 2]
    h_ut = np.broadcast_to(rx_pos[:, None, 2], (p, t))

    ids, inv = np.unique(tx_index, return_inverse=True)
    inv = inv.reshape(p, t)
    pts = np.arange(p)[:, None]
    los_corr = float(tab["los_state_decorrelation_m"]["value"])

    # LoS state (step 2): uniform = Phi(OU process) per transmitter id
    g = _ou_innovations(rx_pos, np.array([los_corr]), ids.size, rng, spatial_consistency)
    u = ndtr(g[..., 0])[pts, inv]                                     # [P, T]
    if los_state is None:
        los = u < tr38901.los_probability(scenario, d_2d, h_ut)
    else:
        los = np.asarray(los_state, dtype=bool)
        if los.shape != (p, t):
            raise ValueError(f"Argument `los_state` must have shape {(p, t)}, not {los.shape}")

    pl = np.where(los, tr38901.pathloss_db(scenario, d_2d, h_bs, h_ut, fc_hz, True),
                  tr38901.pathloss_db(scenario, d_2d, h_bs, h_ut, fc_hz, False))

    lg = np.zeros((p, t, 7))
    mu_zsd = np.zeros((p, t))
    zod_off = np.zeros((p, t))
    for cond in (True, False):
        w = _ou_innovations(rx_pos, tr38901.decorrelation_distances_m(scenario, cond), ids.size,
                            rng, spatial_consistency)[pts, inv]           # [P, T, 7]
        chol = np.linalg.cholesky(tr38901.correlation_matrix(scenario, cond))
        z = np.einsum("ij,ptj->pti", chol, w)
        mu, sd = tr38901.lsp_statistics(scenario, cond, fc_hz, d_2d.ravel(), h_ut.ravel(),
                                        h_bs.ravel())
        vals = mu.reshape(p, t, 7) + sd.reshape(p, t, 7) * z
        sel = los == cond
        lg[sel] = vals[sel]
        mu_zsd[sel] = mu.reshape(p, t, 7)[..., 5][sel]
        zod_off[sel] = tr38901.zod_offset_deg(scenario, cond, fc_hz, d_2d[sel], h_ut[sel])

    clip = tab["lsp"]["clip_deg"]
    return UmaLinkParameters(
        los=los, sf_db=lg[..., 0], k_db=np.where(los, lg[..., 1], np.nan), ds=10.0 ** lg[..., 2],
        asd=np.minimum(10.0 ** lg[..., 3], clip["ASD"]), asa=np.minimum(10.0 ** lg[..., 4], clip["ASA"]),
        zsd=np.minimum(10.0 ** lg[..., 5], clip["ZSD"]), zsa=np.minimum(10.0 ** lg[..., 6], clip["ZSA"]),
        mu_lg_zsd=mu_zsd, zod_offset=zod_off, pathloss_db=pl, d_2d=d_2d)
