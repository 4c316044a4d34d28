"""CP-OFDM modulation and demodulation, normal cyclic prefix (TS 38.211 5.3.1).

Baseband only (the 5.4 up-conversion phase term is omitted). Subcarrier ``k`` of the grid sits at
FFT bin ``k - num_subcarriers/2`` (DC in the middle of the band, no DC null, as in NR). The
transforms are unitary (``norm="ortho"``): the energy of one symbol's useful part equals the
energy of its grid column, so white noise of variance ``s2`` per sample has variance ``s2`` per RE.
"""

from __future__ import annotations

import numpy as np

from ...config.nr import NRConfig
from .prs import SYMBOLS_PER_SLOT

#: kappa * 144 and kappa * 16 of TS 38.211 5.3.1 expressed at the 2048-point FFT of mu = 0
_CP_SHORT_2048 = 144
_CP_EXTRA_2048 = 16


class OFDM:
    """OFDM modulator/demodulator for one numerology, bandwidth and sample rate.

    :param nr: the waveform config (numerology, num_prb, sample_rate_hz)
    """

    def __init__(self, nr: NRConfig):
        nr.validate()
        self.numerology = nr.numerology
        self.num_subcarriers = nr.num_subcarriers
        self.fft_size = nr.fft_size
        self.sample_rate_hz = nr.resolved_sample_rate_hz
        self.subcarrier_spacing_hz = nr.subcarrier_spacing_hz
        self._bins = (np.arange(self.num_subcarriers) - self.num_subcarriers // 2) % self.fft_size

    def cp_lengths(self, slot: int) -> np.ndarray:
        """CP of each symbol of slot ``slot`` (slot index within the frame).

        N_CP,l = 144 kappa 2^-mu + 16 kappa for l = 0 or l = 7 * 2^mu (l counted within the
        subframe), else 144 kappa 2^-mu; converted to samples at this rate.

        :return: cp : [14] int64, samples
        """
        scale = self.fft_size / 2048  # samples per kappa*Tc unit at this rate, mu folded in
        l_sf = (slot % 2**self.numerology) * SYMBOLS_PER_SLOT + np.arange(SYMBOLS_PER_SLOT)
        long = (l_sf % (7 * 2**self.numerology)) == 0
        cp = _CP_SHORT_2048 * scale + long * _CP_EXTRA_2048 * scale * 2**self.numerology
        if np.any(np.abs(cp - np.round(cp)) > 1e-9):
            raise ValueError(f"FFT size {self.fft_size} gives a fractional cyclic prefix")
        return np.round(cp).astype(np.int64)

    def slot_length(self, slot: int) -> int:
        """Samples in slot ``slot``."""
        return int(self.cp_lengths(slot).sum() + SYMBOLS_PER_SLOT * self.fft_size)

    def num_samples(self, slots: np.ndarray | range) -> int:
        return int(sum(self.slot_length(int(s)) for s in slots))

    def symbol_starts(self, slots: np.ndarray | range) -> np.ndarray:
        """Sample index where each symbol's CP starts, relative to the first slot's start.

        :return: start : [num_slots, 14] int64, samples
        """
        starts, pos = [], 0
        for s in slots:
            cp = self.cp_lengths(int(s))
            lens = cp + self.fft_size
            starts.append(pos + np.concatenate(([0], np.cumsum(lens)[:-1])))
            pos += int(lens.sum())
        return np.asarray(starts, dtype=np.int64)

    def modulate(self, grid: np.ndarray, slots: np.ndarray | range | None = None) -> np.ndarray:
        """Grid to waveform.

        :param grid: [..., num_slots, 14, num_subcarriers] complex
        :param slots: slot index (within the frame) of each grid slot; default 0..num_slots-1
        :return: x : [..., num_samples] complex128, baseband at ``sample_rate_hz``
        """
        grid = np.asarray(grid)
        if grid.ndim < 3 or grid.shape[-2:] != (SYMBOLS_PER_SLOT, self.num_subcarriers):
            raise ValueError(f"Argument `grid` must have shape [..., num_slots, 14, "
                             f"{self.num_subcarriers}], not {grid.shape}")
        slots = range(grid.shape[-3]) if slots is None else slots
        lead = grid.shape[:-3]
        freq = np.zeros(lead + grid.shape[-3:-1] + (self.fft_size,), dtype=np.complex128)
        freq[..., self._bins] = grid
        body = np.fft.ifft(freq, axis=-1, norm="ortho")
        pieces = []
        for i, s in enumerate(slots):
            cp = self.cp_lengths(int(s))
            for l in range(SYMBOLS_PER_SLOT):
                sym = body[..., i, l, :]
                pieces.append(sym[..., self.fft_size - cp[l]:])
                pieces.append(sym)
        return np.concatenate(pieces, axis=-1)

    def demodulate(self, x: np.ndarray, slots: np.ndarray | range, offset: int = 0) -> np.ndarray:
        """Waveform to grid: drop each CP and FFT the useful part.

        :param x: [..., num_samples] complex, first slot starting at sample ``offset``
        :param slots: slot indices (within the frame) contained in ``x``
        :param offset: samples before the first slot's first CP
        :return: grid : [..., num_slots, 14, num_subcarriers] complex128
        """
        x = np.asarray(x)
        starts = self.symbol_starts(slots)
        cps = np.stack([self.cp_lengths(int(s)) for s in slots])
        first = offset + starts + cps  # first useful sample of each symbol
        if first.size and first.max() + self.fft_size > x.shape[-1]:
            raise ValueError(f"Argument `x` is too short ({x.shape[-1]} samples) for {len(starts)} slots")
        idx = first[..., None] + np.arange(self.fft_size)
        body = x[..., idx]  # [..., num_slots, 14, fft]
        return np.fft.fft(body, axis=-1, norm="ortho")[..., self._bins]
