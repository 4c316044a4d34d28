"""The threat registry: each attack scenario's adversary as a :class:`Threat` registered by name.

A run's ``run.scenarios`` names threats (and ``'none'``, the benign run);
:class:`~veriloc_rt.attacks.adversary.AdversarySignal` looks each one up in
:data:`THREAT_REGISTRY` and calls its :meth:`Threat.grid` per attack point. The three built-in
threats register here the way a plug-in does (docs/extending.md, "A new attack"):

* ``fbs``: false-BS selective PRS spoofing (:class:`FBSThreat`);
* ``meaconing``: the relay (:class:`MeaconingThreat`);
* ``jamming``: wideband noise over the PRS band (:class:`JammingThreat`).

A threat returns the adversary's transmitted grid ``[num_slots, 14, num_subcarriers]``
complex128 in the chain's unit-RE normalisation (see :mod:`~veriloc_rt.attacks.adversary`:
divide a grid built at absolute RE amplitude by ``signal.unit``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import math
from dataclasses import dataclass
import numpy as np

from ..phy.shortcuts import reference
from ..phy.channel import (Links, apply_frequency, dbm_to_watt, equal_arrival_powers,
                           occupied_power_factor, re_amplitude, receiver_noise_variance)
from ..propagation.cir import CIR
from ..registry import Registry
from ..rng import stream
from .fbs import FalseBaseStation, spoofer_replicas
from .jamming import Jammer
from .meaconing import Meaconer

__all__ = ["AttackPoint", "BENIGN", "FBSThreat", "JammingThreat", "MeaconingThreat",
           "THREAT_REGISTRY", "Threat", "scenario_labels", "scenario_names"]

#: the benign scenario's name (no adversary; not a threat)
BENIGN = "none"


@dataclass(frozen=True, eq=False)
class AttackPoint:
    """What a threat may use at one attack point.

    point : int, trajectory index; frame : int, frame counter of the point
    bs_ue, bs_adv, adv_ue : CIR, the serving BS -> UE, BS -> adversary and adversary -> UE links
    (all points; index them with ``point``); adversary_pos, ue_pos : [3] float64, m
    """

    point: int
    frame: int
    bs_ue: CIR
    bs_adv: CIR
    adv_ue: CIR | None
    adversary_pos: np.ndarray
    ue_pos: np.ndarray


class Threat(ABC):
    """One attack: what its adversary transmits at an attack point.

    Made once per chain by :class:`~veriloc_rt.attacks.adversary.AdversarySignal` (``signal``:
    the run's config ``signal.cfg``, the chain ``signal.chain``, its OFDM numerology
    ``signal.ofdm``, subcarrier frequencies ``signal.freqs``, grid shape ``signal.shape`` and
    unit-RE amplitude ``signal.unit``); :meth:`grid` is called per attack point.

    Class attributes a threat may set: ``label`` (figure legends), ``shared_by_chains`` (True:
    the grid depends on the config and the adversary's draws only, so the standard and the
    DS-tagged chain of one PRS mode reuse one; False: it depends on the chain's own frames, as
    a relay's does), ``relays`` (True: the UE also receives the BS -> adversary Doppler, added
    to the Doppler scan), ``stream_index`` (the integer of the adversary's random stream; None:
    a stream named after the threat).
    """

    #: set by the registry
    name: str = ""
    label: str = ""
    shared_by_chains: bool = True
    relays: bool = False
    stream_index: int | None = None

    def __init__(self, signal):
        self.signal = signal

    @abstractmethod
    def grid(self, at: AttackPoint, rng: np.random.Generator) -> np.ndarray:
        """[num_slots, 14, num_subcarriers] complex128, the transmitted grid (unit-RE
        normalisation); ``rng``: the adversary's own draws at this point."""

    @classmethod
    def rng(cls, seed: int, prs_mode: int, point: int) -> np.random.Generator:
        """The adversary's stream at ``point`` for PRS mode ``prs_mode``."""
        if cls.stream_index is not None:
            return stream(seed, "adversary", cls.stream_index, prs_mode, point)
        return stream(seed, f"adversary:{cls.name}", prs_mode, point)


#: threats by name (``run.scenarios``)
THREAT_REGISTRY: Registry[type[Threat]] = Registry("threat", "run.scenarios")


def scenario_names() -> tuple[str, ...]:
    """Every scenario a run can evaluate: 'none', then the registered threats."""
    return (BENIGN, *THREAT_REGISTRY.names())


def scenario_labels() -> dict[str, str]:
    """``{scenario: figure label}`` of :func:`scenario_names`, in its order (a threat without
    a ``label``: its name)."""
    return {BENIGN: "No Attack",
            **{n: (t.label or n) for n, t in THREAT_REGISTRY.items()}}


@THREAT_REGISTRY.register("fbs")
class FBSThreat(Threat):
    """The sum of the spoofer's standard-PRS replicas (:func:`spoofer_replicas`), replica ``i``
    delayed by ``d_i`` as the per-subcarrier phase ``exp(-j 2 pi f_k d_i)``. The spoofer's power
    is split equally over its replicas; its estimate of the UE is the true UE position (ideal
    tracking, the strongest adversary). With ``threats.fbs.link_gain`` 'spoofed_bs' replica
    ``i`` is scaled by sqrt(G_i / G_adv) (path gains of BS i's and the adversary's links to
    the UE), so that after the adversary's link it arrives with BS i's."""

    label = "FBS"
    stream_index = 1

    def __init__(self, signal):
        super().__init__(signal)
        cfg = signal.cfg
        self.fbs = FalseBaseStation(cfg.threats.fbs, cfg.threats.fbs.spoofed_slots or None)
        # the spoofer sends each replica's PRS, and its tag fill where the network has tags
        fill = cfg.threats.fbs.tag_fill != "none" and cfg.security.tag_scheme != "none"
        self.power_factor = occupied_power_factor(cfg.channel.prs_power, cfg.nr.num_subcarriers,
                                                  cfg.nr.comb, fill)

    def grid(self, at: AttackPoint, rng: np.random.Generator) -> np.ndarray:
        s, cfg = self.signal, self.signal.cfg
        plan = self.fbs(at.bs_ue.tx_pos[at.point], at.adversary_pos, at.ue_pos)
        reps = spoofer_replicas(cfg.nr, at.frame, plan.replicas, rng, slots=s.slots,
                                tag_fill=cfg.threats.fbs.tag_fill,
                                network_tags=cfg.security.tag_scheme != "none")
        out = np.zeros(s.shape, dtype=np.complex128)
        if not reps:
            return out
        amp = float(re_amplitude(self.fbs.power_w / len(reps) * self.power_factor,
                                 s.ofdm)) / s.unit
        link = np.ones(len(reps))
        if cfg.threats.fbs.link_gain == "spoofed_bs":
            # each replica reaches the UE with the gain of the BS it imitates: the chain applies
            # the adversary's link, so scale by the ratio of the two links' path gains
            if at.adv_ue is None:
                raise ValueError("threats.fbs.link_gain 'spoofed_bs' needs the adversary -> UE CIR")
            g_adv = float(Links.from_cir(at.adv_ue, at.point).power_gain()[0])
            g_bs = Links.from_cir(at.bs_ue, at.point).power_gain()
            link = np.array([math.sqrt(g_bs[b] / g_adv) if g_adv > 0 else 0.0 for b, _, _ in reps])
        for (_, delay, grid), g in zip(reps, link):
            # (g grid) ramp, in the replica's own array (a copy): no full-grid temporaries
            np.multiply(g, grid, out=grid)
            np.multiply(grid, s.delay_ramp(delay)[None, None, :], out=grid)
            out += grid
        return amp * out


@THREAT_REGISTRY.register("meaconing")
class MeaconingThreat(Threat):
    """The grid the relay receives from the serving BSs over the ``bs_adv`` links (the BSs
    transmit with the powers the UE's power control set) through its receive antenna gain
    (``meaconing.rx_antenna_gain_dbi``), plus its thermal noise (``meaconing.noise_figure_db``,
    default the UE's), with absolute timing (t0 = 0); then the relay's AGC to
    ``meaconing.power_dbm`` (capped by ``max_gain_db``) and its processing delay as a phase
    ramp: :func:`veriloc_rt.attacks.meaconing.meacon` done on the grid instead of on IQ.

    The relay hears every RE, the tags of every slot too; the tags of the slots the UE does not
    check (frequency domain: the chain's frame leaves them out) reach only the relay's AGC
    and REs the UE never reads. With the shortcut ``relaytags``
    (:mod:`veriloc_rt.phy.shortcuts`) those REs carry the stand-in QPSK symbol
    :data:`STAND_IN` instead of each slot's own tag: the AGC input's power on such an RE,
    ``abs(h x + n)^2`` with the relay's noise n ~ CN(0, sigma^2) independent of everything,
    has the same distribution for every unit-modulus x (n is circularly symmetric), so the
    gain's distribution is unchanged, and the tags of those slots are not computed.
    """

    #: the relay's stand-in symbol on the tag REs the UE does not check (shortcut ``relaytags``)
    STAND_IN = complex(1.0, 1.0) / math.sqrt(2.0)

    label = "Meaconing"
    shared_by_chains = False
    relays = True
    stream_index = 2

    def __init__(self, signal):
        super().__init__(signal)
        cfg = signal.cfg
        self.meaconer = Meaconer(cfg.threats.meaconing)
        mc = cfg.threats.meaconing
        nf = cfg.channel.ue_noise_figure_db if mc.noise_figure_db is None else mc.noise_figure_db
        self.noise_var = receiver_noise_variance(cfg.channel, signal.ofdm.sample_rate_hz, nf)
        self.rx_gain = 10.0 ** (mc.rx_antenna_gain_dbi / 20.0)
        #: the stand-in tags (shortcut ``relaytags``), read when the threat is made
        self.stand_in = not reference("relaytags")
        #: by transmitter (a serving set's): (every tag's occupancy, the flat indices of the
        #: REs it fills and the chain's frame leaves empty)
        self._stand_ins: dict = {}

    def relayed_frame(self, bs_ids: tuple, frame: int) -> tuple[np.ndarray, np.ndarray | None]:
        """The grids the relay receives (every RE: every slot's tags) and their occupancy:
        the chain's frame with every tag, or (``relaytags``) its own frame plus
        :data:`STAND_IN` on the tag REs it leaves empty.

        :return: (grids [num_bs, S, 14, K] complex128, occupied [num_bs, S, 14, K] bool or None)
        """
        chain = self.signal.chain
        if not self.stand_in:
            sig = chain.frame_signals(bs_ids, frame, every_tag=True)
            return sig.grids, sig.occupied
        sig = chain.frame_signals(bs_ids, frame)
        if sig.occupied is None:    # occupancy unknown: the reference's frame
            sig = chain.frame_signals(bs_ids, frame, every_tag=True)
            return sig.grids, sig.occupied
        tx = chain.setup(bs_ids).transmitter
        fill = self._stand_ins.get(tx)
        if fill is None:
            every = tx.occupied(self.signal.slots)[0]
            fill = self._stand_ins[tx] = (every, np.flatnonzero(every & ~sig.occupied).astype(np.int32))
        if not fill[1].size:
            return sig.grids, sig.occupied
        grids = sig.grids.copy()
        grids.reshape(-1)[fill[1]] = self.STAND_IN
        return grids, fill[0]

    def grid(self, at: AttackPoint, rng: np.random.Generator) -> np.ndarray:
        s = self.signal
        point, bs_ue = at.point, at.bs_ue
        bs_ids = tuple(int(b) for b in bs_ue.tx_index[point])
        grids, occupied = self.relayed_frame(bs_ids, at.frame)   # the relay hears every RE
        ch = s.cfg.channel
        powers = equal_arrival_powers(Links.from_cir(bs_ue, point).power_gain(),
                                      float(dbm_to_watt(ch.bs_max_power_dbm)), ch.power_control)
        y = self.rx_gain * apply_frequency(Links.from_cir(at.bs_adv, point), grids,
                                           re_amplitude(powers * s.chain.bs_power_factor,
                                                        s.ofdm), s.ofdm,
                                           s.slots, 0.0, occupied)[0]
        y = s.relay_noise(y, self.noise_var, rng)
        # AGC over the whole input (signal + noise): RE power p means carrier power
        # p N_sc / N_fft (channel module's convention), so the gain is the same as on IQ
        p_in = float(np.mean(np.abs(y) ** 2)) * s.ofdm.num_subcarriers / s.ofdm.fft_size
        cfg = self.meaconer.config
        gain = math.sqrt(self.meaconer.power_w / p_in) if p_in > 0 else 0.0
        if cfg.max_gain_db is not None:
            gain = min(gain, 10.0 ** (cfg.max_gain_db / 20.0))
        out = np.multiply(gain / s.unit, y)
        return np.multiply(out, s.delay_ramp(cfg.processing_delay_s)[None, None, :], out=out)


@THREAT_REGISTRY.register("jamming")
class JammingThreat(Threat):
    """:meth:`~veriloc_rt.attacks.jamming.Jammer.grid`: complex Gaussian noise on every RE of
    the PRS band."""

    label = "Jamming"
    stream_index = 3

    def __init__(self, signal):
        super().__init__(signal)
        self.jammer = Jammer(signal.cfg.nr, signal.cfg.threats.jamming)

    def grid(self, at: AttackPoint, rng: np.random.Generator) -> np.ndarray:
        return self.jammer.grid(self.signal.shape, rng) / self.signal.unit
