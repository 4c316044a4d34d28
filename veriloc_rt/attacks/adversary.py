"""What the adversary of each scenario transmits at one point, as a grid for the chain.

:class:`AdversarySignal` is configured once per run (waveform, channel, threats, the chain whose
BS grids a meaconer relays) and called per point. It returns the adversary's transmitted
resource grid ``[num_slots, 14, num_subcarriers]`` complex128 in the chain's *unit-RE
normalisation*: the chain scales it by ``re_amplitude(channel.adversary_power_dbm)``, so a grid
built at absolute RE amplitude (a unit-RE grid at power P times ``sqrt(P N_fft / N_sc)``) is
divided by that scale here. Each threat's own ``power_dbm`` is therefore what reaches the air.

The threats themselves are registered by name (:mod:`veriloc_rt.attacks.threats`): the
signal looks the scenario up in :data:`~veriloc_rt.attacks.threats.THREAT_REGISTRY` and calls
that threat's ``grid``. Everything is in the frequency domain (exact when every delay relative to the UE's timing
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

A plug-in threat (docs/extending.md) computes its own grid the same way.
"""

from __future__ import annotations

import numpy as np

from ..config import Config
from ..phy.chain import PositioningChain
from ..phy.channel import dbm_to_watt, re_amplitude, subcarrier_frequencies
from ..phy.noise import KeptWhiteNoise
from ..propagation.cir import CIR
from .threats import THREAT_REGISTRY, AttackPoint, Threat

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
        self.relay_noise = KeptWhiteNoise(1) if relay_noise is None else relay_noise
        self.shape = (len(self.slots), 14, self.ofdm.num_subcarriers)
        #: the threats made so far, by scenario name (made on first use)
        self.threats: dict[str, Threat] = {}

    def delay_ramp(self, delay_s: float) -> np.ndarray:
        """[num_subcarriers] complex128, the phase ramp of a delay."""
        return np.exp(-2j * np.pi * self.freqs * delay_s)

    def threat(self, scenario: str) -> Threat:
        """The threat of ``scenario``, made on first use from the registry.

        :raises InputError: ``run.scenarios``: no threat registered under that name
        """
        t = self.threats.get(scenario)
        if t is None:
            t = self.threats[scenario] = THREAT_REGISTRY.get(scenario)(self)
        return t

    def __call__(self, scenario: str, point: int, frame: int, bs_ue: CIR, bs_adv: CIR,
                 adversary_pos: np.ndarray, ue_pos: np.ndarray, rng: np.random.Generator,
                 adv_ue: CIR | None = None) -> np.ndarray:
        """Adversary grid [num_slots, 14, num_subcarriers] complex128 (unit-RE normalisation).

        :param scenario: a registered threat's name ('fbs', 'meaconing', 'jamming', ...)
        :param adversary_pos, ue_pos: [3] float64, m, at this point
        :param rng: the adversary's own draws (spoofer tag fill, relay noise, jamming noise)
        :param adv_ue: the adversary -> UE CIR the chain applies (needed by 'fbs' with
            ``threats.fbs.link_gain`` 'spoofed_bs')
        """
        at = AttackPoint(point, frame, bs_ue, bs_adv, adv_ue, adversary_pos, ue_pos)
        return self.threat(scenario).grid(at, rng)
