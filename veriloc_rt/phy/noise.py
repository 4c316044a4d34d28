"""Noise sources: where a receiver's thermal noise comes from.

A noise source is a small block called on a received signal (a grid ``[A, S, 14, K]`` in the
frequency domain, IQ ``[A, N]`` in the time domain), the per-sample (= per-RE, unitary OFDM)
variance and a generator; it returns the signal plus circular complex Gaussian noise of that
variance, CN(0, sigma^2) per sample (the variance from
:func:`~veriloc_rt.phy.channel.receiver_noise_variance`: k T0 F f_s, Sec. 2 of ITU-R P.372 for
k T0). The chain (:mod:`veriloc_rt.phy.chain`) and the uplink receiver
(:class:`~veriloc_rt.phy.receiver.uplink.UplinkPositioner`) take one each:

* :class:`WhiteNoise` (the run's): i.i.d. draws from the generator of the call, i.e. the run's
  per-point stream ``stream(seed, "noise", 0, point)``; a grid's draws run slot-major, so its
  first slots get the same noise whatever the number of slots.
* :class:`GridNoise`: the noise drawn as a per-RE grid, slot-major, added to a grid or
  OFDM-modulated into IQ (orthonormal: each FFT window gets the grid back exactly; CP and tail
  get none), from a generator supplied to the source (:meth:`GridNoise.supply`) or else the
  call's. Chains of different sample rate, domain or number of slots then see the same noise on
  the same REs (the fidelity bench compares them so).

``follows_call_rng`` says whether the draws depend on the call's generator alone: only then may
a caller keep a received signal per generator state and give it back with the generator moved
past the draws (:class:`veriloc_rt.phy.chain.downlink.DownlinkChannel`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from .channel import add_noise, draw_grid_noise_on, draw_grid_noise_slots, draw_noise
from .nr.ofdm import OFDM
from .nr.prs import SYMBOLS_PER_SLOT
from ..rng import KeptDraw

__all__ = ["GridNoise", "KeptWhiteNoise", "NoiseSource", "WhiteNoise"]


class NoiseSource(ABC):
    """Adds a receiver's thermal noise: the interface of :class:`WhiteNoise` and :class:`GridNoise`."""

    #: the draws depend only on the generator passed to the call
    follows_call_rng: bool = True

    @abstractmethod
    def __call__(self, x: np.ndarray, variance: float, rng: np.random.Generator) -> np.ndarray:
        """``x`` plus noise of ``variance`` per sample (a new complex128 array).

        :param x: [A, S, 14, K] complex grid or [A, N] complex IQ
        :param variance: float, W per sample and RE (0: no noise, ``x`` copied)
        :param rng: the call's generator
        """

    def add_on_read(self, x: np.ndarray, variance: float, rng: np.random.Generator,
                    read: np.ndarray | None, single: bool = False,
                    overwrite_x: bool = False) -> np.ndarray:
        """As the call, told which REs of a grid the receiver reads: a source may leave the
        others without noise (this one gives every RE its noise), and may draw its normals in
        single precision (this one does not).

        :param read: grids only: [S', 14, K] bool (S' >= S), the REs read (None: every RE)
        :param single: single-precision normals allowed (the shortcut ``noise32`` of
            :mod:`veriloc_rt.phy.shortcuts`: :func:`~veriloc_rt.phy.channel.standard_normals`)
        :param overwrite_x: the caller will not read ``x`` again: a source may add the noise
            into it and return it (the same values as a new array)
        """
        return self(x, variance, rng)


def _overrides_call(source: NoiseSource, cls: type) -> bool:
    """``source``'s class overrides ``cls``'s call (to record or change the noise): it then gets
    every call, with every RE's noise."""
    return type(source).__call__ is not cls.__call__


class WhiteNoise(NoiseSource):
    """i.i.d. CN(0, variance) per sample from the call's generator; a grid's draws run along the
    slots outermost (:func:`~veriloc_rt.phy.channel.add_noise` with ``major_axis`` 1). Given the
    REs the receiver reads (:meth:`add_on_read`), a grid gets noise on those alone
    (:func:`~veriloc_rt.phy.channel.draw_grid_noise_on`, the same order of draws): what the
    receiver sees has the same distribution, for fewer draws; told ``single``, from
    single-precision normals (the same distribution, cheaper draws). A subclass that overrides the call
    (to record or change the noise) gets every call instead, with every RE's noise."""

    follows_call_rng = True

    def __call__(self, x: np.ndarray, variance: float, rng: np.random.Generator) -> np.ndarray:
        return add_noise(x, variance, rng, major_axis=1 if x.ndim == 4 else 0)

    def add_on_read(self, x: np.ndarray, variance: float, rng: np.random.Generator,
                    read: np.ndarray | None, single: bool = False,
                    overwrite_x: bool = False) -> np.ndarray:
        if x.ndim != 4:
            read = None
        if (read is None and not single) or variance <= 0 or _overrides_call(self, WhiteNoise):
            return self(x, variance, rng)
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
        if read is None:
            return add_noise(x, variance, rng, major_axis=1 if x.ndim == 4 else 0, single=True)
        n = draw_grid_noise_on(x.shape, read, variance, rng, single)
        n += x
        return n


class KeptWhiteNoise(WhiteNoise):
    """:class:`WhiteNoise` that keeps its last draws: a call from a generator in the state of a
    kept draw, for a signal of the same shape and variance, gets the same noise without drawing
    it again, and the generator moved past the draws as if drawn. Chains handed the same
    generator state at one point (a run's standard-PRS and encrypted-PRS chains: common random
    numbers, one thermal noise per point) then draw it once. A grid's noise is drawn slot by
    slot (:func:`~veriloc_rt.phy.channel.draw_grid_noise_slots`, the same values), so a grid of
    the first slots alone (a chain decoding tags on another's timing) gets the first slots of a
    kept draw of more slots with the same REs read in them, and the generator in the state
    after those slots' draws: what drawing them would give.

    :param size: draws kept (the oldest is dropped)
    """

    follows_call_rng = True

    def __init__(self, size: int = 4):
        self.size = int(size)
        self._kept = KeptDraw(size)
        #: kept grid draws, the last first: (state on entry, (A, 14, K), variance, single,
        #: read mask [S, 14, K] or None, noise [A, S, 14, K], state after each slot)
        self._grids: list[tuple] = []

    def __call__(self, x: np.ndarray, variance: float, rng: np.random.Generator) -> np.ndarray:
        return self.add_on_read(x, variance, rng, None)

    def add_on_read(self, x: np.ndarray, variance: float, rng: np.random.Generator,
                    read: np.ndarray | None, single: bool = False,
                    overwrite_x: bool = False) -> np.ndarray:
        if variance <= 0 or not isinstance(rng, np.random.Generator):
            return WhiteNoise.__call__(self, x, variance, rng)   # a copy, or the type error
        if _overrides_call(self, KeptWhiteNoise):
            return self(x, variance, rng)
        single = bool(single)
        if x.ndim == 4:
            noise = self.grid_noise(x.shape, variance, rng, read, single)
            if overwrite_x and x.dtype == np.complex128 and x.flags.writeable:
                # x + noise in x's own array: the bits of noise + x (a sum's parts commute),
                # without a new grid (7 MB on the paper config: 1-2 ms a call)
                return np.add(x, noise, out=x)
            return noise + x

        def draw():
            n = draw_noise(x.shape, variance, rng, 0, single)
            n.flags.writeable = False
            return n

        return self._kept((x.shape, variance, None, single), rng, draw) + x

    def grid_noise(self, shape: tuple, variance: float, rng: np.random.Generator,
                   read: np.ndarray | None, single: bool = False) -> np.ndarray:
        """The noise of a grid of ``shape`` (A, S, 14, K) on the REs ``read`` (None: every RE),
        read-only: kept, or the first S slots of a kept draw of more slots, with ``rng`` moved
        past the draws; else drawn (:func:`~veriloc_rt.phy.channel.draw_grid_noise_slots`)."""
        a, s, rest = shape[0], shape[1], tuple(shape[2:])
        if s == 0:
            return np.zeros(shape, dtype=np.complex128)
        mask = None if read is None else np.asarray(read, dtype=bool)[:s]
        state = rng.bit_generator.state
        for e in self._grids:
            start, dims, var, one, emask, noise, after = e
            if (noise.shape[1] >= s and dims == (a,) + rest and var == variance and one == single
                    and (emask is None) == (mask is None)
                    and (mask is None or np.array_equal(emask[:s], mask)) and start == state):
                rng.bit_generator.state = after[s - 1]
                return noise if noise.shape[1] == s else noise[:, :s]
        noise, after = draw_grid_noise_slots(shape, read, variance, rng, single)
        noise.flags.writeable = False
        if mask is not None:
            mask = mask.copy()
            mask.flags.writeable = False
        self._grids = [(state, (a,) + rest, variance, single, mask, noise, after)] + self._grids[:self.size - 1]
        return noise


class GridNoise(NoiseSource):
    """Noise drawn as a per-RE grid ``[A, S, 14, K]``, slot-major, for every signal form.

    :param ofdm: the receiver's OFDM (subcarriers; modulation of the grid into IQ)
    :param slots: the frame's slot numbers
    :param rng: the generator the draws come from (None: the call's); :meth:`supply` replaces it
    """

    def __init__(self, ofdm: OFDM, slots, rng: np.random.Generator | None = None):
        self.ofdm, self.slots = ofdm, slots
        self.rng = None
        self.supply(rng)

    @property
    def follows_call_rng(self) -> bool:   # type: ignore[override]
        return self.rng is None

    def supply(self, rng: np.random.Generator | None) -> None:
        """Draw from ``rng`` from now on (None: from the call's generator)."""
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
        self.rng = rng

    def __call__(self, x: np.ndarray, variance: float, rng: np.random.Generator) -> np.ndarray:
        # (add_on_read gives every RE its noise too: chains of different layouts then see the
        # same noise on the same REs)
        if variance <= 0:
            return add_noise(x, variance, rng)
        src = self.rng if self.rng is not None else rng
        num_slots = x.shape[1] if x.ndim == 4 else len(self.slots)   # a grid may hold the first slots
        shape = (x.shape[0], num_slots, SYMBOLS_PER_SLOT, self.ofdm.num_subcarriers)
        g = add_noise(np.zeros(shape, dtype=np.complex128), variance, src, major_axis=1)
        if x.ndim == 4:
            return x + g
        iq = self.ofdm.modulate(g, self.slots)
        out = np.array(x, dtype=np.complex128)
        out[:, :iq.shape[-1]] += iq
        return out
