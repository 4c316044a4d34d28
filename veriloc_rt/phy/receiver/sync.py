"""Receiver front ends: received signal + local replica -> per-block cross-spectra.

* :func:`frequency_cross_spectra` (fast path): the received resource grid times the conjugate
  replica, one block per replica symbol; the bins are the subcarriers, ``f_k = (k - N_sc/2) SCS``.
  Correlating per RE is the time-domain correlation of each symbol's FFT window with its replica,
  evaluated only on the occupied subcarriers.
* :func:`time_cross_spectra` (reference): for each replica symbol (CP included), the linear
  correlation of the IQ buffer with the replica samples at lags in [-guard, window], computed by
  FFT; only the in-band bins (|f| <= (N_sc/2 + 2) SCS) are kept, which is an ideal channel
  filter and leaves the correlation inside the band unchanged.

:func:`noise_variance` estimates the per-RE noise variance from the symbols no serving signal
uses (the PRS occupies at most 12 of 14 symbols, the SRS a few).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.fft as sfft

from ..channel import (as_slice, kept, kept_by_id, occupancy_groups, subcarrier_frequencies,
                       symbol_layout)
from ..nr.ofdm import OFDM
from .toa import CrossSpectra, spatial_covariance_stats, spatial_dof

__all__ = ["frequency_cross_spectra", "frequency_cross_spectra_many", "time_cross_spectra",
           "noise_variance", "noise_estimates", "noise_dof", "block_index"]


def block_index(replica: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(slot, symbol) of every replica symbol with a non-zero RE.

    :param replica: [num_slots, 14, num_subcarriers] complex
    :returns: slot_idx, sym_idx : [num_blocks] int64
    """
    used = np.any(replica != 0, axis=-1)
    s, l = np.nonzero(used)
    return s, l


def _block_times(ofdm: OFDM, slots, s_idx: np.ndarray, l_idx: np.ndarray) -> np.ndarray:
    starts, cps = symbol_layout(ofdm, slots)
    return (starts[s_idx, l_idx] + cps[s_idx, l_idx] + (ofdm.fft_size - 1) / 2.0) / ofdm.sample_rate_hz


#: (s_idx, l_idx, groups) by the replica's RE pattern: a chain's replicas occupy the same REs
#: at every point
_LAYOUTS: dict = {}


def _replica_layout(replica: np.ndarray, occupied: np.ndarray | None = None) -> tuple:
    """The replica's blocks and their groups: ``(s_idx, l_idx, groups)``, ``s_idx, l_idx`` as
    :func:`block_index`, ``groups`` None (every block occupies every bin) or per group of
    :func:`~veriloc_rt.phy.channel.occupancy_groups` ``(blocks, bins, the blocks' slots, their
    symbols, the bins as a slice or index array)`` (kept per pattern).

    :param occupied: ``replica != 0`` when the caller knows it, else None
    """
    occ = replica != 0 if occupied is None else occupied

    def make():
        s_idx, l_idx = np.nonzero(np.any(occ, axis=-1))
        groups = occupancy_groups(occ[s_idx, l_idx])
        if groups is not None:
            groups = [(b, k, s_idx[b], l_idx[b], as_slice(k)) for b, k in groups]
        return s_idx, l_idx, groups

    return kept(_LAYOUTS, occ.tobytes() + str(occ.shape).encode(), make)


#: what :func:`_replica_terms` derived from read-only replicas, by the replica and its mask
#: (:func:`~veriloc_rt.phy.channel.kept_by_id`)
_TERMS: dict[tuple, tuple] = {}
#: replicas whose terms are kept (a chain's frame holds one per serving BS and replica mode; an
#: entry is about 2 MB)
_TERMS_MAX = 16


def _replica_terms(replica: np.ndarray, occupied: np.ndarray | None) -> tuple:
    """``(s_idx, l_idx, groups, dense, ref_power)`` of a replica: the layout of
    :func:`_replica_layout`; ``dense`` conj(X) [1, B, K] of every block when ``groups`` is None
    (else None); per group ``(blocks, bins, slots, symbols, bins index, conj(X) [1, B_g, K_g])``;
    ``ref_power`` |X|^2 [B, K] (0 off the replica's REs). Read-only arrays, kept for a read-only
    replica (a frame's, used by every chain and scenario of its point) and made afresh for a
    writable one."""
    def make():
        s_idx, l_idx, groups = _replica_layout(replica, occupied)
        rep = replica[s_idx, l_idx]                                   # [B, K]
        if groups is None:
            dense, parts, ref_power = np.conj(rep)[None], None, np.abs(rep) ** 2
        else:   # only the replica's REs: S = Y X* is zero elsewhere
            dense, parts = None, []
            ref_power = np.zeros(rep.shape)   # |X|^2: 0 off the replica's REs
            for b, k, sb, lb, ix in groups:
                if isinstance(ix, slice):
                    x = rep[b, ix]
                    ref_power[b, ix] = np.abs(x) ** 2
                else:
                    x = rep[b[:, None], ix[None, :]]
                    ref_power[b[:, None], ix[None, :]] = np.abs(x) ** 2
                cx = np.conj(x)[None]
                cx.flags.writeable = False
                parts.append((b, k, sb, lb, ix, cx))
            parts = tuple(parts)
        for a in (dense, ref_power):
            if a is not None:
                a.flags.writeable = False
        return s_idx, l_idx, parts, dense, ref_power

    if replica.flags.writeable:
        return make()
    return kept_by_id(_TERMS, (replica, occupied), make, max_entries=_TERMS_MAX)


def _check_grid(rx_grid: np.ndarray, replica: np.ndarray, occupied: np.ndarray | None) -> None:
    if rx_grid.ndim != 4 or rx_grid.shape[1:] != replica.shape:
        raise ValueError(f"Arguments `rx_grid` {rx_grid.shape} and `replica` {replica.shape} "
                         "must be [A, S, 14, K] and [S, 14, K]")
    if occupied is not None and occupied.shape != replica.shape:
        raise ValueError(f"Argument `occupied` {occupied.shape} must have the shape of `replica` "
                         f"{replica.shape}")


def frequency_cross_spectra(rx_grid: np.ndarray, replica: np.ndarray, ofdm: OFDM, slots,
                            occupied: np.ndarray | None = None) -> CrossSpectra:
    """Per-RE cross-spectra of a received grid with a replica grid, computed on the replica's
    REs only when it leaves some empty (``CrossSpectra.parts``; a comb-6 PRS: 1/6 of them).

    :param rx_grid: [num_ant, num_slots, 14, num_subcarriers] complex
    :param replica: [num_slots, 14, num_subcarriers] complex (0 off the replica's REs)
    :param occupied: [num_slots, 14, num_subcarriers] bool, ``replica != 0`` when the caller
        knows it (:meth:`~veriloc_rt.phy.transmitter.PRSTransmitter.occupied`), else None
    """
    return frequency_cross_spectra_many(rx_grid, [replica], ofdm, slots,
                                        None if occupied is None else [occupied])[0]


def frequency_cross_spectra_many(rx_grid: np.ndarray, replicas: Sequence[np.ndarray], ofdm: OFDM,
                                 slots, occupied: Sequence[np.ndarray | None] | None = None
                                 ) -> list[CrossSpectra]:
    """:func:`frequency_cross_spectra` of each of several replicas on one received grid (the
    serving TRPs' PRS), the same values, the groups of blocks (slot, symbol) that the replicas
    share taken one after the other: the TRPs of a comb-N PRS occupy the same symbols with
    different comb offsets, and each gather reads most of its symbols' cache lines for 1/N of
    their values, which the next TRP's gather of the same symbols then finds in the cache.

    :param replicas: per replica [S, 14, K] complex
    :param occupied: per replica ``replica != 0`` or None (see :func:`frequency_cross_spectra`)
    """
    rx_grid = np.asarray(rx_grid)
    occupied = [None] * len(replicas) if occupied is None else list(occupied)
    if len(occupied) != len(replicas):
        raise ValueError(f"Arguments `replicas` ({len(replicas)}) and `occupied` ({len(occupied)}) "
                         "must have one entry per replica")
    for rep, occ in zip(replicas, occupied):
        _check_grid(rx_grid, rep, occ)
    terms = [_replica_terms(rep, occ) for rep, occ in zip(replicas, occupied)]
    # the groups of every replica by the blocks they read, each block set's groups one after
    # the other: the grid's rows they share are read from the cache after the first
    by_rows: dict = {}
    for r, t in enumerate(terms):
        for g, grp in enumerate(t[2] or ()):
            by_rows.setdefault((grp[2].tobytes(), grp[3].tobytes()), []).append((r, g))
    products: dict = {}
    for members in by_rows.values():
        for r, g in members:
            _, _, sb, lb, ix, cx = terms[r][2][g]
            if isinstance(ix, slice):   # (the grid may be a strided view: no reshape, which
                y = rx_grid[:, sb, lb, ix]   # would copy it whole)
            else:
                y = rx_grid[:, sb[:, None], lb[:, None], ix[None, :]]
            # C order [A, B_g, K_g]: the gather leaves the blocks outermost, and the products
            # over the antennas' rows (spatial_dof, CrossSpectra.at_delay) then copy it whole
            products[r, g] = np.multiply(y, cx, order="C")
    freqs = subcarrier_frequencies(ofdm)
    band = ofdm.num_subcarriers * ofdm.subcarrier_spacing_hz
    out = []
    for r, (s_idx, l_idx, groups, dense, ref_power) in enumerate(terms):
        if groups is None:
            parts, spectra = None, np.multiply(rx_grid[:, s_idx, l_idx, :], dense, order="C")   # [A, B, K]
        else:   # only the replica's REs: S = Y X* is zero elsewhere
            spectra = None
            parts = tuple((grp[0], grp[1], products[r, g]) for g, grp in enumerate(groups))
        out.append(CrossSpectra(spectra=spectra, freqs=freqs,
                                bin_spacing_hz=ofdm.subcarrier_spacing_hz,
                                block_times=_block_times(ofdm, slots, s_idx, l_idx),
                                ref_power=ref_power, band_hz=band, parts=parts))
    return out


def time_cross_spectra(rx_iq: np.ndarray, replica: np.ndarray, ofdm: OFDM, slots, guard_s: float,
                       window_s: float) -> CrossSpectra:
    """Per-symbol time-domain correlation of an IQ buffer with the replica waveform.

    :param rx_iq: [num_ant, num_samples] complex, the buffer (sample 0 = timing reference)
    :param replica: [num_slots, 14, num_subcarriers] complex, replica grid (modulated here)
    :param guard_s, window_s: lags searched, [-guard_s, window_s], s
    """
    rx_iq = np.asarray(rx_iq)
    fs = ofdm.sample_rate_hz
    wave = ofdm.modulate(replica, slots)
    s_idx, l_idx = block_index(replica)
    starts, cps = symbol_layout(ofdm, slots)
    starts, cps = starts[s_idx, l_idx], cps[s_idx, l_idx]
    lens = cps + ofdm.fft_size
    g = int(np.ceil(guard_s * fs)) + 2
    w = int(np.ceil(window_s * fs)) + 2
    n_f = sfft.next_fast_len(int(lens.max()) + g + w + 1)
    need = int(starts.max()) + n_f
    ypad = np.zeros((rx_iq.shape[0], need + g), dtype=np.complex128)
    n_copy = min(rx_iq.shape[1], need)
    ypad[:, g:g + n_copy] = rx_iq[:, :n_copy]
    seg_idx = starts[:, None] + np.arange(n_f)[None, :]          # into ypad: y[start - g + n]
    s_seg = np.zeros((len(starts), n_f), dtype=np.complex128)
    for b, (st, ln) in enumerate(zip(starts, lens)):
        s_seg[b, :ln] = wave[st:st + ln]
    f = sfft.fftfreq(n_f, 1.0 / fs)
    keep = np.abs(f) <= (ofdm.num_subcarriers / 2 + 2) * ofdm.subcarrier_spacing_hz
    f = f[keep]
    s_f = sfft.fft(s_seg, axis=-1)[..., keep]
    shift = np.exp(2j * np.pi * f * g / fs)                       # lag 0 at the block start
    spectra = np.empty((rx_iq.shape[0],) + s_f.shape, dtype=np.complex128)
    for a in range(rx_iq.shape[0]):                               # one antenna at a time: memory
        y_f = sfft.fft(ypad[a, seg_idx], axis=-1)[..., keep]      # [B, bins]
        spectra[a] = y_f * np.conj(s_f) * (shift / n_f)
    return CrossSpectra(spectra=spectra, freqs=f, bin_spacing_hz=fs / n_f,
                        block_times=_block_times(ofdm, slots, s_idx, l_idx),
                        ref_power=np.abs(s_f) ** 2 / n_f,
                        band_hz=ofdm.num_subcarriers * ofdm.subcarrier_spacing_hz)


def _free_symbols(rx_grid: np.ndarray, busy_symbols) -> list[int]:
    busy = {int(b) for b in busy_symbols}
    return [l for l in range(rx_grid.shape[-2]) if l not in busy]


def _mean_power(x: np.ndarray) -> float:
    """``np.mean(np.abs(x) ** 2)`` (the same value), the square taken in place."""
    p = np.abs(x)
    np.square(p, out=p)
    return float(np.mean(p))


def noise_estimates(rx_grid: np.ndarray, busy_symbols, hermitian: bool = False) -> tuple[float, float]:
    """``(noise_variance(rx_grid, busy_symbols), noise_dof(rx_grid, busy_symbols))``, the same
    values from one gather of the free symbols.

    :param hermitian: both from one Hermitian rank-k update of the free symbols (the shortcut
        ``dofherk``: the mean power is tr R / (A N), R's trace; the same sums in another order)
    """
    a = rx_grid.shape[0]
    free = _free_symbols(rx_grid, busy_symbols)
    if not free:
        return float("nan"), 2.0 * a
    x = rx_grid[..., free, :]
    if hermitian and x.dtype == np.complex128:
        tr, dof = spatial_covariance_stats(x.reshape(a, -1), True)
        return tr / x.size, dof
    return _mean_power(x), spatial_dof(x.reshape(a, -1))


def noise_variance(rx_grid: np.ndarray, busy_symbols) -> float:
    """Mean |Y|^2 over the symbols no serving signal uses: per-RE noise variance.

    :param rx_grid: [num_ant, num_slots, 14, num_subcarriers] complex
    :param busy_symbols: symbol indices (0..13) carrying signals
    :returns: float (NaN when every symbol is busy)
    """
    free = _free_symbols(rx_grid, busy_symbols)
    if not free:
        return float("nan")
    return _mean_power(rx_grid[..., free, :])


def noise_dof(rx_grid: np.ndarray, busy_symbols) -> float:
    """Effective degrees of freedom of the antenna-summed noise on the free symbols.

    White noise, independent per antenna, gives 2 A; noise from one direction (a jammer, a
    relay's amplified noise) is coherent across the array and gives 2: its sum over antennas
    has the tail of a single exponential, which a 2 A-dof threshold underestimates by several
    dB. See :func:`~veriloc_rt.phy.receiver.toa.spatial_dof`.

    :param rx_grid: [num_ant, num_slots, 14, num_subcarriers] complex
    :returns: float in [2, 2 num_ant] (2 num_ant when every symbol is busy)
    """
    a = rx_grid.shape[0]
    free = _free_symbols(rx_grid, busy_symbols)
    if not free:
        return 2.0 * a
    return spatial_dof(rx_grid[..., free, :].reshape(a, -1))
