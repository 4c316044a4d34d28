"""Uplink positioning for the DL-UL handshake: the UE's SRS timed at the serving BSs.

The UE transmits its SRS-like reference (:func:`veriloc_rt.phy.nr.srs.srs_grid`) from one antenna
at the array centre; each serving BS receives it through the reciprocal of its downlink CIR
(same delays and Doppler, the UE's single-antenna gain: :meth:`Links.uplink_from_cir`) with its
own thermal noise (frequency domain: drawn only on the REs the receiver reads, the shortcut
``ulnoise`` of :mod:`veriloc_rt.phy.shortcuts`), and times it with the same ToA estimator as
the UE. The BSs are synchronised but the UE's transmit time is unknown, so the arrival-time
differences ``toa_j - toa_0`` are uplink TDOAs with exactly the algebra of DL RSTDs and go to
the same :class:`~veriloc_rt.phy.receiver.multilateration.Multilaterator`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..channel import (Links, apply_frequency, apply_time, dbm_to_watt, re_amplitude,
                       receiver_noise_variance)
from ..noise import NoiseSource, WhiteNoise
from ..shortcuts import reference
from ...config.channel import ChannelConfig, ReceiverConfig
from ...config.nr import NRConfig
from ..nr.ofdm import OFDM
from ..nr.srs import srs_grid
from .multilateration import MultilaterationResult, Multilaterator
from .sync import frequency_cross_spectra, noise_variance, time_cross_spectra
from .toa import ToAEstimator

__all__ = ["UplinkResult", "UplinkPositioner"]


@dataclass(frozen=True, eq=False)
class UplinkResult:
    """Uplink timing at the serving BSs and the network's fix of the UE.

    detected : [num_bs] bool
    toa_s : [num_bs] float64, s, arrival time at each BS (absolute up to the UE's unknown
        transmit offset; NaN where not detected)
    tdoa_s : [num_bs] float64, s, toa_j - toa_0 (NaN where not detected)
    peak_snr_db : [num_bs] float64, dB
    position : MultilaterationResult, the UL fix
    """

    detected: np.ndarray
    toa_s: np.ndarray
    tdoa_s: np.ndarray
    peak_snr_db: np.ndarray
    position: MultilaterationResult


class UplinkPositioner:
    """Receives the UE's SRS at each serving BS and solves the uplink position.

    :param nr: waveform config (bandwidth, numerology, sample rate, slots per frame)
    :param channel: channel config (domain, UE power, BS noise figure, timing guard)
    :param receiver: receiver config (SRS parameters, ToA rule, thresholds)
    :param noise: the BSs' noise source (default :class:`~veriloc_rt.phy.noise.WhiteNoise`, from
        the call's generator)

    In the frequency domain the noise source is told the REs the receiver reads
    (:attr:`read`: the SRS's REs and every RE of the symbols outside ``receiver.srs_symbols``,
    which :func:`~veriloc_rt.phy.receiver.sync.noise_variance` reads), and a
    :class:`~veriloc_rt.phy.noise.WhiteNoise` draws it on those alone, in the reference's order
    of draws (the shortcut ``ulnoise``). With a :class:`~veriloc_rt.phy.noise.WhiteNoise` the
    noise estimate is drawn from its distribution instead (the shortcut ``ulnoisevar``): those
    symbols hold the noise alone (the SRS and, per RE, its channel leave them empty; no
    adversary reaches the uplink), so the mean of ``|n|^2`` over their M REs, i.i.d. CN(0,
    sigma^2), is Gamma(M, sigma^2 / M) (the sum of M exponentials of mean sigma^2), one draw
    from the call's generator after the BS's noise, and :attr:`read` is the SRS's REs alone.
    Each shortcut is left out when ``VERILOC_RT_REFERENCE`` names it when the positioner is
    built.
    """

    def __init__(self, nr: NRConfig, channel: ChannelConfig, receiver: ReceiverConfig,
                 noise: NoiseSource | None = None):
        self.nr, self.channel, self.receiver = nr, channel, receiver
        self.noise = noise if noise is not None else WhiteNoise()
        self.ofdm = OFDM(nr)
        self.slots = range(nr.slots_per_frame)
        one = srs_grid(nr.num_prb, receiver.srs_n_id, receiver.srs_comb, 0, tuple(receiver.srs_symbols))
        self.grid = np.broadcast_to(one, (len(self.slots),) + one.shape).copy()  # [S, 14, K]
        self.grid.flags.writeable = False   # the replica: its cross-spectra terms are kept
        #: [S, 14, K] bool, the SRS's REs (``grid != 0``, computed once)
        self.occupied = self.grid != 0
        self.waveform = self.ofdm.modulate(self.grid, self.slots) if channel.domain == "time" else None
        period = 1.0 / (receiver.srs_comb * nr.subcarrier_spacing_hz)
        window = min(receiver.search_window_s, 0.9 * period - channel.timing_guard_s)
        self.toa = ToAEstimator(replace(receiver, search_window_s=window), channel.timing_guard_s)
        self.noise_var = receiver_noise_variance(channel, self.ofdm.sample_rate_hz, channel.bs_noise_figure_db)
        #: the symbols (0..13) the noise estimate averages: those outside ``srs_symbols``
        self.free = tuple(s for s in range(self.grid.shape[1]) if s not in set(receiver.srs_symbols))
        #: the noise estimate drawn from its distribution (the shortcut ``ulnoisevar``)
        self.direct_variance = (channel.domain == "frequency" and bool(self.free)
                                and type(self.noise) is WhiteNoise and not reference("ulnoisevar"))
        #: [S, 14, K] bool, the REs the receiver reads (frequency domain, the shortcut
        #: ``ulnoise``), else None (noise on every RE)
        self.read = None
        if channel.domain == "frequency" and not reference("ulnoise"):
            read = self.occupied.copy()
            if not self.direct_variance:
                read[:, list(self.free)] = True
            read.flags.writeable = False
            self.read = read

    def receive(self, link: Links, t0: float, rng: np.random.Generator) -> np.ndarray:
        """One BS's received signal: grid [1, S, 14, K] (frequency) or IQ [1, N] (time); with
        :attr:`read`, the grid's other REs hold the signal without noise."""
        amp = re_amplitude([dbm_to_watt(self.channel.ue_power_dbm)], self.ofdm)
        if self.channel.domain == "frequency":
            y = apply_frequency(link, self.grid[None], amp, self.ofdm, self.slots, t0, self.occupied[None])
        else:
            n = self.waveform.shape[-1] + int(np.ceil(self.receiver.search_window_s * self.ofdm.sample_rate_hz)) + 64
            dec = max(1, min(self.channel.time_decimation, self.ofdm.fft_size // self.nr.min_fft_size))
            y = apply_time(link, self.waveform[None], amp, self.ofdm.sample_rate_hz, t0, n, dec)
        return self.noise.add_on_read(y, self.noise_var, rng, self.read)

    def noise_estimate(self, grid: np.ndarray, rng: np.random.Generator) -> float:
        """The per-RE noise variance of a BS's received grid [A, S, 14, K] the ToA estimator is
        given: :func:`~veriloc_rt.phy.receiver.sync.noise_variance` over the symbols without
        SRS, or (:attr:`direct_variance`, the shortcut ``ulnoisevar``) its value drawn from its
        distribution, Gamma(M, sigma^2 / M) for M REs, one draw from ``rng``."""
        if self.direct_variance and self.noise_var > 0:
            m = grid.shape[0] * grid.shape[1] * len(self.free) * grid.shape[-1]
            return float(rng.gamma(m, self.noise_var / m))
        return noise_variance(grid, tuple(self.receiver.srs_symbols))

    def __call__(self, uplinks: list[Links], bs_pos: np.ndarray, ue_height_m: float,
                 rng: np.random.Generator, solve=None) -> UplinkResult:
        """Time the SRS at every BS and solve the UL position.

        :param uplinks: one single-antenna :class:`Links` per serving BS (reference first)
        :param bs_pos: [num_bs, 3] float64, m
        :param solve: the fix from the TDOAs: ``solve(detected, toa_s, peak_snr_db, bs_pos,
            ue_height_m) -> MultilaterationResult`` (the chain passes its DL fix's solver, so
            the network's fit weighs, tests and excludes as the UE's does); None: the unweighted
            :class:`Multilaterator` with BS 0 the reference and ``receiver.max_residual_m``
        """
        if len(uplinks) != len(bs_pos):
            raise ValueError(f"Arguments `uplinks` ({len(uplinks)}) and `bs_pos` ({len(bs_pos)}) "
                             "must have one entry per BS")
        firsts = np.array([lk.first_delay()[0] for lk in uplinks])
        t0 = float(np.nanmin(firsts) - self.channel.timing_guard_s) if np.any(np.isfinite(firsts)) else 0.0
        n_bs = len(uplinks)
        det = np.zeros(n_bs, dtype=bool)
        toa = np.full(n_bs, np.nan)
        snr = np.full(n_bs, -np.inf)
        for j, link in enumerate(uplinks):
            y = self.receive(link, t0, rng)
            grid = y if self.channel.domain == "frequency" else self.ofdm.demodulate(y, self.slots)
            if self.channel.per_re_receiver:
                cs = frequency_cross_spectra(grid, self.grid, self.ofdm, self.slots, self.occupied)
            else:
                cs = time_cross_spectra(y, self.grid, self.ofdm, self.slots, self.channel.timing_guard_s,
                                        self.toa.cfg.search_window_s)
            nv = self.noise_estimate(grid, rng)
            est = self.toa(cs, nv if np.isfinite(nv) else self.noise_var)
            det[j], snr[j] = est.detected, est.peak_snr_db
            toa[j] = t0 + est.toa_s if est.detected else np.nan
        tdoa = toa - toa[0]
        if solve is not None:
            fix = solve(det, toa, snr, np.asarray(bs_pos, dtype=float), ue_height_m)
        else:
            solver = Multilaterator(ue_height_m=ue_height_m, max_residual_m=self.receiver.max_residual_m)
            fix = solver(np.asarray(bs_pos, dtype=float), np.where(det, tdoa, np.nan), 0, det)
        return UplinkResult(det, toa, tdoa, snr, fix)
