"""What the adversary of each scenario transmits at one point, as a grid for the chain.

:class:`AdversarySignal` is configured once per run (waveform, channel, threats, the chain whose
BS grids a meaconer relays) and called per point. It returns the adversary's transmitted
resource grid ``[num_slots, 14, num_subcarriers]`` complex128 in the chain's *unit-RE
normalisation*: the chain scales it by ``re_amplitude(channel.adversary_power_dbm)``, so a grid
built at absolute RE amplitude (a unit-RE grid at power P times ``sqrt(P N_fft / N_sc)``) is
divided by that scale here. Each threat's own ``power_dbm`` is therefore what reaches the air.

Everything is in the frequency domain (exact when every delay relative to the UE's timing
reference lies within the cyclic prefix, as :func:`veriloc_rt.phy.channel.apply_frequency` assumes):

* **fbs**: the sum of the spoofer's standard-PRS replicas (:func:`spoofer_replicas`), replica
  ``i`` delayed by ``d_i`` as the per-subcarrier phase ``exp(-j 2 pi f_k d_i)`` (``f_k`` the
  baseband subcarrier frequency, the channel module's convention). The spoofer's power is split
  equally over its replicas. The adversary's estimate of the UE is the true UE position (ideal
  tracking, the strongest adversary; documented choice). With ``threats.fbs.link_gain``
  'spoofed_bs' replica ``i`` is scaled by sqrt(G_i / G_adv) (path gains of BS i's and the
  adversary's links to the UE), so that after the adversary's link it arrives with BS i's.
* **meaconing**: the grid the adversary receives from the serving BSs over the ``bs_adv`` links
  (the BSs transmit with the powers the UE's power control set) through its receive antenna
  gain (``meaconing.rx_antenna_gain_dbi``), plus its thermal noise (``meaconing.noise_figure_db``,
  default the UE's), with absolute timing (t0 = 0); then the relay's AGC to
  ``meaconing.power_dbm`` (capped by ``max_gain_db``) and its processing delay as a phase ramp.
  This is :func:`veriloc_rt.attacks.meaconing.meacon` done on the grid instead of on IQ.
* **jamming**: :meth:`Jammer.grid`, complex Gaussian noise on every RE of the PRS band.
"""

from __future__ import annotations

import math

import numpy as np

from ..phy.channel import (Links, apply_frequency, dbm_to_watt, equal_arrival_powers,
                           occupied_power_factor, re_amplitude, subcarrier_frequencies,
                           receiver_noise_variance)
from ..phy.noise import KeptWhiteNoise
from ..config import Config
from ..propagation.cir import CIR
from ..phy.chain import PositioningChain
from .fbs import FalseBaseStation, spoofer_replicas
from .jamming import Jammer
from .meaconing import Meaconer

__all__ = ["AdversarySignal"]


class AdversarySignal:
    """Per-point adversary grids of one run.

    :param cfg: the run config (nr, channel, security, threats)
    :param chain: the chain the signal is for (its OFDM, slots and BS grids are used)
    :param relay_noise: the relay's thermal noise (default: its own
        :class:`~veriloc_rt.phy.noise.KeptWhiteNoise`); the signals of chains handed the same
        generator state at a point (the standard and the DS-tagged chain: one PRS mode, one
        adversary stream) share one to draw that noise once
    """

    def __init__(self, cfg: Config, chain: PositioningChain,
                 relay_noise: KeptWhiteNoise | None = None):
        self.cfg, self.chain = cfg, chain
        self.ofdm = chain.ofdm
        self.slots = chain.slots
        self.freqs = subcarrier_frequencies(self.ofdm)
        self.unit = float(re_amplitude(dbm_to_watt(cfg.channel.adversary_power_dbm), self.ofdm))
        self.fbs = FalseBaseStation(cfg.threats.fbs, cfg.threats.fbs.spoofed_slots or None)
        # the spoofer sends each replica's PRS, and its tag fill where the network has tags
        fill = cfg.threats.fbs.tag_fill != "none" and cfg.security.tag_scheme != "none"
        self.fbs_power_factor = occupied_power_factor(cfg.channel.prs_power, cfg.nr.num_subcarriers,
                                                      cfg.nr.comb, fill)
        self.meaconer = Meaconer(cfg.threats.meaconing)
        self.jammer = Jammer(cfg.nr, cfg.threats.jamming)
        fs = self.ofdm.sample_rate_hz
        mc = cfg.threats.meaconing
        nf = cfg.channel.ue_noise_figure_db if mc.noise_figure_db is None else mc.noise_figure_db
        self.adv_noise_var = receiver_noise_variance(cfg.channel, fs, nf)
        self.relay_rx_gain = 10.0 ** (mc.rx_antenna_gain_dbi / 20.0)
        self.relay_noise = KeptWhiteNoise(1) if relay_noise is None else relay_noise
        self.shape = (len(self.slots), 14, self.ofdm.num_subcarriers)

    def _delay(self, delay_s: float) -> np.ndarray:
        """[num_subcarriers] complex128, the phase ramp of a delay."""
        return np.exp(-2j * np.pi * self.freqs * delay_s)

    def __call__(self, scenario: str, point: int, frame: int, bs_ue: CIR, bs_adv: CIR,
                 adversary_pos: np.ndarray, ue_pos: np.ndarray, rng: np.random.Generator,
                 adv_ue: CIR | None = None) -> np.ndarray:
        """Adversary grid [num_slots, 14, num_subcarriers] complex128 (unit-RE normalisation).

        :param scenario: 'fbs', 'meaconing' or 'jamming'
        :param adversary_pos, ue_pos: [3] float64, m, at this point
        :param rng: the adversary's own draws (spoofer tag fill, relay noise, jamming noise)
        :param adv_ue: the adversary -> UE CIR the chain applies (needed by 'fbs' with
            ``threats.fbs.link_gain`` 'spoofed_bs')
        """
        if scenario == "fbs":
            return self._fbs(point, frame, bs_ue, adversary_pos, ue_pos, rng, adv_ue)
        if scenario == "meaconing":
            return self._meaconing(point, frame, bs_ue, bs_adv, rng)
        if scenario == "jamming":
            return self.jammer.grid(self.shape, rng) / self.unit
        raise ValueError(f"Argument `scenario` must be one of 'fbs', 'meaconing', 'jamming', "
                         f"not {scenario!r}")

    def _fbs(self, point, frame, bs_ue, adversary_pos, ue_pos, rng, adv_ue) -> np.ndarray:
        plan = self.fbs(bs_ue.tx_pos[point], adversary_pos, ue_pos)
        reps = spoofer_replicas(self.cfg.nr, frame, plan.replicas, rng, slots=self.slots,
                                tag_fill=self.cfg.threats.fbs.tag_fill,
                                network_tags=self.cfg.security.tag_scheme != "none")
        out = np.zeros(self.shape, dtype=np.complex128)
        if not reps:
            return out
        amp = float(re_amplitude(self.fbs.power_w / len(reps) * self.fbs_power_factor,
                                 self.ofdm)) / self.unit
        link = np.ones(len(reps))
        if self.cfg.threats.fbs.link_gain == "spoofed_bs":
            # each replica reaches the UE with the gain of the BS it imitates: the chain applies
            # the adversary's link, so scale by the ratio of the two links' path gains
            if adv_ue is None:
                raise ValueError("threats.fbs.link_gain 'spoofed_bs' needs the adversary -> UE CIR")
            g_adv = float(Links.from_cir(adv_ue, point).power_gain()[0])
            g_bs = Links.from_cir(bs_ue, point).power_gain()
            link = np.array([math.sqrt(g_bs[b] / g_adv) if g_adv > 0 else 0.0 for b, _, _ in reps])
        for (_, delay, grid), s in zip(reps, link):
            out += (s * grid) * self._delay(delay)[None, None, :]
        return amp * out

    def _meaconing(self, point, frame, bs_ue, bs_adv, rng) -> np.ndarray:
        bs_ids = tuple(int(b) for b in bs_ue.tx_index[point])
        sig = self.chain.frame_signals(bs_ids, frame, every_tag=True)   # the relay hears every RE
        grids = sig.grids
        ch = self.cfg.channel
        powers = equal_arrival_powers(Links.from_cir(bs_ue, point).power_gain(),
                                      float(dbm_to_watt(ch.bs_max_power_dbm)), ch.power_control)
        y = self.relay_rx_gain * apply_frequency(Links.from_cir(bs_adv, point), grids,
                                                 re_amplitude(powers * self.chain.bs_power_factor,
                                                              self.ofdm), self.ofdm,
                                                 self.slots, 0.0, sig.occupied)[0]
        y = self.relay_noise(y, self.adv_noise_var, rng)
        # AGC over the whole input (signal + noise): RE power p means carrier power
        # p N_sc / N_fft (channel module's convention), so the gain is the same as on IQ
        p_in = float(np.mean(np.abs(y) ** 2)) * self.ofdm.num_subcarriers / self.ofdm.fft_size
        cfg = self.meaconer.config
        gain = math.sqrt(self.meaconer.power_w / p_in) if p_in > 0 else 0.0
        if cfg.max_gain_db is not None:
            gain = min(gain, 10.0 ** (cfg.max_gain_db / 20.0))
        return (gain / self.unit) * y * self._delay(cfg.processing_delay_s)[None, None, :]
