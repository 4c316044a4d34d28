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

from ..phy.channel import add_noise
from ..config import Config
from ..constants import SPEED_OF_LIGHT
from ..phy.nr.ofdm import SYMBOLS_PER_SLOT
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
    seconds_per_point : float, s, chain time only, the first point excluded (it also fills
        the chain's caches) when there are two or more
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


def _grid_noise(x: np.ndarray, variance: float, rng: np.random.Generator, ofdm, slots) -> np.ndarray:
    """x plus noise drawn as a per-RE grid, slot-major (the first S slots' draws do not depend on
    how many follow): added to a grid [A, S, 14, K], or OFDM-modulated (orthonormal: each FFT
    window gets the grid back exactly; CP and tail get no noise) into IQ [A, N]."""
    shape = (x.shape[0], len(slots), SYMBOLS_PER_SLOT, ofdm.num_subcarriers)
    g = add_noise(np.zeros(shape, dtype=np.complex128), variance, rng, major_axis=1)   # [A, S, 14, K]
    if x.ndim == 4:
        return x + g
    iq = ofdm.modulate(g, slots)
    out = np.array(x, dtype=np.complex128)
    out[:, :iq.shape[-1]] += iq
    return out


def shared_noise_chain():
    """A :class:`PositioningChain` whose downlink (from ``dl_rng``) and uplink (from the point's
    generator) noise is drawn by :func:`_grid_noise`: every chain with the same bandwidth sees
    the same noise on the same REs, whatever its sample rate, domain or number of slots (its
    first slots). Time domain: for the ``ofdm`` front end only."""
    from ..phy.receiver.chain import PositioningChain
    from ..phy.receiver.uplink import UplinkPositioner

    class SharedNoiseUplink(UplinkPositioner):
        def _add_noise(self, y, rng):
            if self.noise_var <= 0:
                return super()._add_noise(y, rng)
            return _grid_noise(y, self.noise_var, rng, self.ofdm, self.slots)

    class SharedNoiseChain(PositioningChain):
        dl_rng: np.random.Generator | None = None
        keep_benign = False   # the noise comes from dl_rng, not from the key's generator

        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            if self.uplink is not None:
                self.uplink = SharedNoiseUplink(self.nr, self.channel, self.receiver)

        def _add_noise(self, x, rng):
            if self.dl_rng is None or self.noise_var <= 0:
                return super()._add_noise(x, rng)
            return _grid_noise(x, self.noise_var, self.dl_rng, self.ofdm, self.slots)

    return SharedNoiseChain


def benign_chain(cfg: Config, geometry, bs_ue, keys, points, noise: str = "noise",
                 progress=None, shared_noise: bool = False) -> BenignRun:
    """Run ``cfg``'s standard chain on ``bs_ue`` at ``points`` without an adversary.

    :param geometry: the run's :class:`~veriloc_rt.world.geometry.Geometry` (true UE positions)
    :param bs_ue: CIR [num_points, num_bs] serving BS -> UE
    :param keys: by BS id (:func:`veriloc_rt.sim.run_folder.run_keys`)
    :param noise: name of the noise stream (another name: other noise draws)
    :param progress: called as ``progress(done, total)``
    :param shared_noise: the noise is a per-RE grid drawn slot-major (:func:`_grid_noise`;
        downlink from its own stream ``noise + "/dl"``, uplink from the point's), so that chains
        of different sample rate, domain (time domain: ``channel.time_front_end`` 'ofdm' only)
        and number of slots see the same noise on the same REs. Off: the run's own draws, as in
        ``veriloc-rt run``.
    """
    from ..detectors import ABSADetector, HandshakeDetector, TagDetector
    from ..detectors.absa import geometric_azimuth
    from ..phy.receiver.chain import PositioningChain

    points = np.asarray(points, dtype=np.int64)
    if shared_noise and cfg.channel.domain == "time" and cfg.channel.time_front_end != "ofdm":
        raise ValueError("shared noise reaches only the FFT windows: the time domain needs "
                         "channel.time_front_end 'ofdm'")
    cls = shared_noise_chain() if shared_noise else PositioningChain
    chain = cls(cfg.nr, cfg.security, cfg.channel, cfg.receiver,
                cfg.propagation.ue_array, cfg.propagation.carrier_frequency_hz, keys)
    d = cfg.detectors
    hmac, absa, hs = TagDetector(d.hmac), ABSADetector(d.absa), HandshakeDetector(d.handshake)
    n, b = len(points), chain.num_bs
    toa, az = np.full((n, b), np.nan), np.full((n, b), np.nan)
    pos = np.full((n, 2), np.nan)
    dec = np.zeros((n, 4), dtype=bool)
    truth = geometry.ue.pos[points]
    bs = bs_ue.tx_pos[points]
    los_delay = np.linalg.norm(bs - truth[:, None, :], axis=-1) / SPEED_OF_LIGHT
    geo_az = np.stack([geometric_azimuth(bs[r], truth[r]) for r in range(n)]) if n else np.zeros((0, b))
    elapsed = 0.0
    for r, i in enumerate(points):
        if shared_noise:
            chain.dl_rng = stream(cfg.seed, noise + "/dl", 0, int(i))
        t = time.perf_counter()
        res = chain(bs_ue, int(i), stream(cfg.seed, noise, 0, int(i)), frame=int(i),
                    reference_azimuth=geo_az[r])
        if r > 0 or n == 1:   # the first call also fills the chain's caches (PRS, keys, FFT plans)
            elapsed += time.perf_counter() - t
        toa[r] = res.toa_s
        az[r] = res.azimuth
        ok = res.position.ok
        if ok:
            pos[r] = res.position.position[:2]
        ul = res.uplink.position if res.uplink is not None else None
        dec[r] = (ok, hmac(res.tags_valid, res.detected).valid,
                  absa(res.azimuth, bs[r], reference_position=truth[r]).valid,
                  hs(res.position.position if ok else None,
                     ul.position if (ul is not None and ul.ok) else None).valid)
        if progress:
            progress(r + 1, n)
    return BenignRun(points, toa, los_delay, az, geo_az, pos, truth[:, :2], dec,
                     elapsed / max(n - 1, 1))
