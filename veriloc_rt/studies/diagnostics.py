"""Benign per-point chain diagnostics: timing, angle and position errors against the geometry.

Used by ``veriloc-rt bench`` (deviation of a fidelity setting from the reference) and
``veriloc-rt compare`` (ray tracing against TR 38.901 UMa). The chain is the run's standard-PRS
chain and every point draws its noise from the run's stream (``stream(seed, "noise", 0, i)``),
so the numbers are those of the ``none`` scenario of ``veriloc-rt run``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..config import Config
from ..constants import SPEED_OF_LIGHT
from ..detectors import PointDetectors, point_verdicts
from ..detectors.absa import geometric_azimuth
from ..phy.chain import PositioningChain
from ..phy.nr.ofdm import OFDM
from ..phy.noise import GridNoise
from ..rng import stream

__all__ = ["BenignRun", "benign_chain", "finite_percentiles", "wrap_deg"]


@dataclass
class BenignRun:
    """The standard chain on benign points.

    points : [P] int64, trajectory indices
    toa : [P, B] float64, s, absolute ToA estimate (NaN: BS not detected)
    los_delay : [P, B] float64, s, straight-line BS -> UE delay (the ToA a perfect receiver
        would report in line of sight)
    az : [P, B] float64, rad, AoA estimate resolved against the true geometry (NaN: none)
    geo_az : [P, B] float64, rad, azimuth from the UE towards each BS
    pos : [P, 2] float64, m, DL fix (NaN: none); truth : [P, 2] float64, m
    decisions : [P, 4] bool: fix obtained, HMAC tags of every BS valid, ABSA (against the true
        geometry), DL-UL handshake
    seconds_per_point : float, s, the chain's CPU time per point (the calling thread's: the
        chain runs in one thread, BLAS pinned to one), the first point excluded (it also fills
        the chain's caches) when there are two or more; with several passes the least
    """

    points: np.ndarray
    toa: np.ndarray
    los_delay: np.ndarray
    az: np.ndarray
    geo_az: np.ndarray
    pos: np.ndarray
    truth: np.ndarray
    decisions: np.ndarray
    seconds_per_point: float

    def same_results(self, other: "BenignRun") -> bool:
        """Whether ``other`` (a later run of the same chain on the same points) gave these
        results: ToAs, AoAs, fixes and decisions equal, NaNs where these have NaNs."""
        return (np.array_equal(self.points, other.points)
                and all(np.array_equal(a, b, equal_nan=True) for a, b in
                        ((self.toa, other.toa), (self.az, other.az), (self.pos, other.pos)))
                and np.array_equal(self.decisions, other.decisions))

    @property
    def toa_bias_m(self) -> np.ndarray:
        """[P, B] float64, m, (ToA - LoS delay) c; only meaningful with a common clock, i.e. up
        to the UE's clock offset, which this simulator does not model (BSs transmit at t = 0)."""
        return (self.toa - self.los_delay) * SPEED_OF_LIGHT

    @property
    def rstd_error_m(self) -> np.ndarray:
        """[P, B - 1] float64, m, RSTD error of each BS against the reference BS 0."""
        est = self.toa[:, 1:] - self.toa[:, :1]
        true = self.los_delay[:, 1:] - self.los_delay[:, :1]
        return (est - true) * SPEED_OF_LIGHT

    @property
    def aoa_error_deg(self) -> np.ndarray:
        """[P, B] float64, deg, |AoA - geometric azimuth| wrapped to [0, 180]."""
        return wrap_deg(self.az - self.geo_az)

    @property
    def position_error_m(self) -> np.ndarray:
        """[P] float64, m, horizontal DL error (NaN without a fix)."""
        return np.linalg.norm(self.pos - self.truth, axis=1)


def finite_percentiles(x, percentiles) -> dict:
    """{"p<q>": percentile} over the finite values of ``x`` (None for every q when none)."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    return {f"p{q:g}": (float(np.percentile(x, q)) if x.size else None) for q in percentiles}


def wrap_deg(a) -> np.ndarray:
    """|a| wrapped to [0, 180] deg, a in rad."""
    return np.abs((np.rad2deg(a) + 180.0) % 360.0 - 180.0)


def benign_chain(cfg: Config, geometry, bs_ue, keys, points, noise: str = "noise",
                 progress=None, shared_noise: bool = False, passes: int = 1) -> BenignRun:
    """Run ``cfg``'s standard chain on ``bs_ue`` at ``points`` without an adversary.

    :param geometry: the run's :class:`~veriloc_rt.world.geometry.Geometry` (true UE positions)
    :param bs_ue: CIR [num_points, num_bs] serving BS -> UE
    :param keys: by BS id (:func:`veriloc_rt.sim.run_folder.run_keys`)
    :param noise: name of the noise stream (another name: other noise draws)
    :param progress: called as ``progress(done, total)``
    :param shared_noise: the noise is a per-RE grid drawn slot-major
        (:class:`~veriloc_rt.phy.noise.GridNoise`; downlink from its own stream
        ``noise + "/dl"`` supplied per point, uplink from the point's), so that chains
        of different sample rate, domain (time domain: ``channel.time_front_end`` 'ofdm' only)
        and number of slots see the same noise on the same REs. Off: the run's own draws, as in
        ``veriloc-rt run``.
    :param passes: times the points are run; the cost is the least pass's (a pass is slowed
        by what else the machine does, never sped up), the results the first pass's, and every
        later pass must give the same ones (RuntimeError otherwise: the chain kept state)
    """
    if not isinstance(passes, (int, np.integer)) or passes < 1:
        raise ValueError(f"Argument `passes` must be an int >= 1, not {passes!r}")
    points = np.asarray(points, dtype=np.int64)
    if shared_noise and cfg.channel.domain == "time" and cfg.channel.time_front_end != "ofdm":
        raise ValueError("shared noise reaches only the FFT windows: the time domain needs "
                         "channel.time_front_end 'ofdm'")
    dl_noise = ul_noise = None
    if shared_noise:
        ofdm, slots = OFDM(cfg.nr), range(cfg.nr.slots_per_frame)
        dl_noise, ul_noise = GridNoise(ofdm, slots), GridNoise(ofdm, slots)
    # benign links only: the scan fitted to the BS -> UE paths' Doppler (the run's rule)
    chain = PositioningChain.from_config(cfg, keys, max_doppler_hz=bs_ue.max_doppler_hz(),
                                         noise=dl_noise, uplink_noise=ul_noise)
    detectors = PointDetectors.from_config(cfg.detectors)
    n, b = len(points), chain.num_bs
    toa, az = np.full((n, b), np.nan), np.full((n, b), np.nan)
    pos = np.full((n, 2), np.nan)
    dec = np.zeros((n, 4), dtype=bool)
    truth = geometry.ue.pos[points]
    bs = bs_ue.tx_pos[points]
    los_delay = np.linalg.norm(bs - truth[:, None, :], axis=-1) / SPEED_OF_LIGHT
    geo_az = np.stack([geometric_azimuth(bs[r], truth[r]) for r in range(n)]) if n else np.zeros((0, b))
    costs, results = [], []
    for k in range(passes):
        elapsed = 0.0
        for r, i in enumerate(points):
            if dl_noise is not None:
                dl_noise.supply(stream(cfg.seed, noise + "/dl", 0, int(i)))
            t = time.thread_time()
            res = chain(bs_ue, int(i), stream(cfg.seed, noise, 0, int(i)), frame=int(i),
                        reference_azimuth=geo_az[r])
            if r > 0 or n == 1:   # the first call also fills the chain's caches (PRS, keys, FFT plans)
                elapsed += time.thread_time() - t
            if k == 0:
                results.append(res)
            elif not (np.array_equal(res.toa_s, results[r].toa_s, equal_nan=True)
                      and np.array_equal(res.position.position, results[r].position.position,
                                         equal_nan=True)):
                raise RuntimeError(f"pass {k + 1} at point {int(i)} differs from the first: the "
                                   "chain keeps state from call to call")
            if progress:
                progress(k * n + r + 1, passes * n)
        costs.append(elapsed / max(n - 1, 1))
    for r, res in enumerate(results):
        toa[r] = res.toa_s
        az[r] = res.azimuth
        ok = res.position.ok
        if ok:
            pos[r] = res.position.position[:2]
        # ABSA against the true position (a run's reference is its last validated one)
        v = point_verdicts(detectors, res, bs[r], truth[r])
        dec[r] = (ok, v["HMAC"], v["ABSA"], v["Handshake"])
    return BenignRun(points, toa, los_delay, az, geo_az, pos, truth[:, :2], dec, min(costs))
