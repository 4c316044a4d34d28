"""The channel stage: a point's links, power control, the received signal with noise and the
adversary's signal.

:class:`DownlinkChannel` turns a point's CIRs into :class:`DownlinkLinks` (links, transmit powers
after power control, the receiver's timing reference) and then into what the UE receives
(:class:`Received`): the serving BSs' frame through their links
(:mod:`veriloc_rt.phy.channel`, frequency or time domain), the receiver's noise (a
:class:`~veriloc_rt.phy.noise.NoiseSource`), plus the adversary's signal through its link.

The serving BSs' signal plus noise does not depend on the adversary, so a run evaluating several
scenarios at one point computes it once: :class:`KeptDraw` keeps the last one under a
:class:`SignalKey` and the generator's state on entry, and a call with the same key and state
gets it back with the generator moved past the noise draws, as if drawn again.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ...config.channel import ChannelConfig
from ...propagation.cir import CIR
from ..channel import (Links, apply_frequency, apply_time, dbm_to_watt, equal_arrival_powers,
                       kept_by_id, re_amplitude, timing_reference)
from ..nr.ofdm import OFDM
from ..noise import NoiseSource
from ..shortcuts import reference
from ...rng import KeptDraw
from .frames import FrameSignals

__all__ = ["Adversary", "DownlinkChannel", "DownlinkLinks", "KeptDraw", "Received", "SignalKey"]


#: per thread: the links of the last points' CIRs (:func:`point_links`)
_POINT_LINKS = threading.local()
#: (CIR, point) pairs whose links are kept: a point's serving links and the adversary's link
#: to the UE, asked for by every chain of every scenario at that point
POINT_LINKS_MAX = 4


def point_links(cir: CIR, point: int) -> Links:
    """``Links.from_cir(cir, point)``, kept per thread under the CIR's identity (a CIR's arrays
    do not change) and the point, read-only: the chains of a point (standard, DS-tagged,
    encrypted PRS) and its scenarios take the same links from the same CIRs."""
    store = getattr(_POINT_LINKS, "store", None)
    if store is None:
        store = _POINT_LINKS.store = {}

    def make():
        links = Links.from_cir(cir, point)
        for a in (links.delays, links.gains, links.doppler, links.valid):
            a.flags.writeable = False
        return links

    return kept_by_id(store, (cir,), make, key=(int(point),), max_entries=POINT_LINKS_MAX)


@dataclass(frozen=True, eq=False)
class Adversary:
    """What the adversary transmits and its link to the UE.

    cir : CIR [num_points, 1], adversary -> UE
    signal : in the unit-RE normalisation of the BSs' grids: a grid [num_slots, 14,
        num_subcarriers] complex aligned with the frame, or IQ [num_samples] complex at
        ``nr.resolved_sample_rate_hz`` starting at t = 0
    """

    cir: CIR
    signal: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.cir, CIR):
            raise TypeError(f"Argument `cir` must be a CIR, not {type(self.cir).__name__}")
        object.__setattr__(self, "signal", np.asarray(self.signal))
        if self.signal.ndim not in (1, 3):
            raise ValueError(f"Argument `signal` must be a grid [S, 14, K] or IQ [N], not "
                             f"shape {self.signal.shape}")


@dataclass(frozen=True, eq=False)
class DownlinkLinks:
    """One point's downlink.

    links : Links, serving BS -> UE; tx_power_w : [num_bs] float64, W, after power control
    amplitudes : [num_bs] float64, per-RE amplitude of each BS's grid (unit-RE normalisation)
    timing_reference_s : float, s, t0, the receiver's timing reference
    adversary : Links or None, adversary -> UE; adversary_signal : as :attr:`Adversary.signal`
    """

    links: Links
    tx_power_w: np.ndarray
    amplitudes: np.ndarray
    timing_reference_s: float
    adversary: Links | None = None
    adversary_signal: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Received:
    """What the UE's array receives: grid [A, S, 14, K] complex128 (after the receiver's OFDM
    demodulation in the time domain); iq [A, N] complex128 (time domain, else None).

    benign : the serving BSs' signal plus noise (:meth:`DownlinkChannel.benign`) when ``grid`` is
        it plus an adversary's signal confined to ``touched``, else None
    touched : [S, 14, K] bool, the REs the adversary's signal reaches (frequency domain: its
        grid's nonzero REs; ``grid`` equals ``benign`` on every other RE), else None
    """

    grid: np.ndarray
    iq: np.ndarray | None
    benign: np.ndarray | None = None
    touched: np.ndarray | None = None

    @property
    def plain(self) -> bool:
        """A per-RE grid with no adversary's signal in it (what a later grid may add to)."""
        return self.benign is None and self.touched is None and self.iq is None

    def adds_to(self, grid: np.ndarray) -> bool:
        """``grid`` (the very array) plus an adversary's signal confined to :attr:`touched`."""
        return self.touched is not None and self.benign is grid

    def reaches(self, mask: np.ndarray, slots=None) -> bool:
        """The adversary's signal reaches an RE of ``mask`` (bool, broadcast against
        :attr:`touched` [S, 14, K]: [S, 14, K], [14, K] in every slot, [14, 1] whole symbols) in
        ``slots`` (indices; None: every slot). Only with :attr:`touched`."""
        t = self.touched if slots is None else self.touched[list(slots)]
        return bool(np.any(t & mask))


@dataclass(frozen=True)
class SignalKey:
    """What a received signal depends on besides the generator: the CIR (the same object: a CIR
    compares by identity), the point, the frame, the replica mode and the number of slots."""

    cir: CIR
    point: int
    frame: int
    replica: str
    num_slots: int


class DownlinkChannel:
    """Links, power control and the received signal of a chain.

    :param channel: channel config (powers, power control, domain, guard, adversary power)
    :param ofdm: the waveform's OFDM; slots: the frame's slot numbers
    :param bs_power_factor: carrier power to PRS-RE power (:func:`~veriloc_rt.phy.channel.occupied_power_factor`)
    :param buffer_samples: length of the received IQ (time domain)
    :param decimation: time-domain path application decimation
    :param noise: the UE's noise source; noise_var: its variance per sample, W
    :param read_symbols: symbols (0..13) whose every RE the receiver reads (its noise estimate's
        free symbols); read_slots: indices of the frame's slots whose every RE it reads (the tag
        checks'); with both given, frequency domain, the noise is drawn only on these and on
        the PRS replicas' REs (the shortcut ``noise`` of :mod:`veriloc_rt.phy.shortcuts`)

    The noise's normals are drawn in single precision (the shortcut ``noise32``) unless
    ``VERILOC_RT_REFERENCE`` names it when the channel is built.
    """

    def __init__(self, channel: ChannelConfig, ofdm: OFDM, slots, bs_power_factor: float,
                 buffer_samples: int, decimation: int, noise: NoiseSource, noise_var: float,
                 read_symbols=None, read_slots=None):
        self.channel, self.ofdm, self.slots = channel, ofdm, slots
        #: [14, 1] bool and slot indices the receiver reads whole (None: noise on every RE)
        self._read_whole = None
        if (read_symbols is not None and read_slots is not None and channel.domain == "frequency"
                and not reference("noise")):
            sym = np.zeros((14, 1), dtype=bool)
            sym[list(read_symbols)] = True
            self._read_whole = (sym, tuple(int(s) for s in read_slots))
        self._read_kept: tuple = (None, None)   # (replica_occupied, its read mask)
        #: the UE's noise from single-precision normals (the shortcut ``noise32``)
        self.single_noise = not reference("noise32")
        self.bs_power_factor = float(bs_power_factor)
        self.buffer_samples, self.decimation = int(buffer_samples), int(decimation)
        self.noise, self.noise_var = noise, float(noise_var)
        self.frame_samples = ofdm.num_samples(slots)
        self.adversary_amplitude = re_amplitude([dbm_to_watt(channel.adversary_power_dbm)], ofdm)
        self._kept = KeptDraw()

    def links(self, bs_ue: CIR, point: int, adversary: Adversary | None = None) -> DownlinkLinks:
        """The links of point ``point``, the powers after power control and t0."""
        links = point_links(bs_ue, point)
        powers = equal_arrival_powers(links.power_gain(), float(dbm_to_watt(self.channel.bs_max_power_dbm)),
                                      self.channel.power_control)
        amps = re_amplitude(powers * self.bs_power_factor, self.ofdm)
        t0 = timing_reference(links, self.channel.timing_guard_s)
        if adversary is None:
            return DownlinkLinks(links, powers, amps, t0)
        return DownlinkLinks(links, powers, amps, t0, point_links(adversary.cir, point),
                             adversary.signal)

    def read_mask(self, frame: FrameSignals) -> np.ndarray | None:
        """[S, 14, K] bool, the REs the receiver reads in ``frame`` (None: every RE, or not
        known): every replica's REs, the whole symbols and slots given at construction."""
        if self._read_whole is None or frame.replica_occupied is None:
            return None
        if self._read_kept[0] is frame.replica_occupied:
            return self._read_kept[1]
        sym, slots = self._read_whole
        read = np.logical_or.reduce(frame.replica_occupied) | sym
        read[list(slots)] = True
        read.flags.writeable = False
        self._read_kept = (frame.replica_occupied, read)
        return read

    def benign(self, dl: DownlinkLinks, frame: FrameSignals, rng: np.random.Generator,
               num_slots: int, key: SignalKey | None = None) -> np.ndarray:
        """The serving BSs' signal plus noise (read-only): grid [A, num_slots, 14, K] or IQ [A, N].

        :param key: identifies it for :class:`KeptDraw` (None, or a noise source whose draws
            do not follow ``rng`` alone: not kept)
        """
        t0 = dl.timing_reference_s

        def compute():
            if self.channel.domain == "frequency":
                occ = None if frame.occupied is None else frame.occupied[:, :num_slots]
                x = apply_frequency(dl.links, frame.grids[:, :num_slots], dl.amplitudes, self.ofdm,
                                    self.slots[:num_slots], t0, occ)
            else:
                x = apply_time(dl.links, frame.waveform, dl.amplitudes, self.ofdm.sample_rate_hz, t0,
                               self.buffer_samples, self.decimation)
            x = self.noise.add_on_read(x, self.noise_var, rng, self.read_mask(frame),
                                      self.single_noise, overwrite_x=True)   # x is ours
            x.flags.writeable = False
            return x

        if key is None or not self.noise.follows_call_rng:
            return compute()
        return self._kept(key, rng, compute)

    def __call__(self, dl: DownlinkLinks, frame: FrameSignals, rng: np.random.Generator,
                 num_slots: int | None = None, key: SignalKey | None = None) -> Received:
        """What the UE receives: the serving BSs' signal plus noise (:meth:`benign`) plus the
        adversary's signal.

        :param num_slots: frequency domain only: the grid of the first ``num_slots`` slots alone
            (the same values as those slots of the whole grid: the noise is drawn slot-major)
        """
        fs = self.ofdm.sample_rate_hz
        t0 = dl.timing_reference_s
        m = len(self.slots) if num_slots is None else num_slots
        base = self.benign(dl, frame, rng, m, key)
        adv, sig, amp = dl.adversary, dl.adversary_signal, self.adversary_amplitude
        if self.channel.domain == "frequency":
            if adv is None:
                return Received(base, None)
            slots = self.slots[:m]
            if sig.ndim == 3:   # per RE: nothing reaches the REs its grid leaves empty
                touched = sig[:m] != 0
                # base + y, in y's own array (added in the pass that applies the link)
                y = apply_frequency(adv, sig[None, :m], amp, self.ofdm, slots, t0, touched[None],
                                    base=base)
                return Received(y, None, base, touched)
            iq = apply_time(adv, sig[None], amp, fs, t0, self.frame_samples, self.decimation)
            return Received(base + self.ofdm.demodulate(iq, self.slots)[:, :m], None)
        iq = base
        if adv is not None:
            wave = self.ofdm.modulate(sig, self.slots) if sig.ndim == 3 else sig
            iq = iq + apply_time(adv, wave[None], amp, fs, t0, self.buffer_samples, self.decimation)
        return Received(self.ofdm.demodulate(iq, self.slots), iq)
