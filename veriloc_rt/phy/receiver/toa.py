"""Doppler scan, timing and ToA from per-block cross-spectra with a local replica.

Both receiver front ends (:mod:`veriloc_rt.phy.receiver.sync`) reduce the received signal and the
replica of one transmitter to *cross-spectra*: for each block b (a PRS symbol) and antenna a, a
set of in-band frequency bins with

    c_ab(tau) = sum_k S_abk exp(j 2 pi f_k tau),

the correlation of the block's received samples with the block's replica at lag tau (exact for
the time-domain front end, per-RE products ``Y X*`` for the frequency-domain one). From them,
:class:`ToAEstimator`

1. scans Doppler: C_a(tau, nu) = sum_b c_ab(tau) exp(-j 2 pi nu t_b); the metric
   max_tau sum_a |C_a|^2 on a grid of nu, refined by parabolic interpolation;
2. corrects the residual phase: the phase of the per-block peaks, derotated by nu, is regressed
   on t_b and the slope refines nu;
3. forms the delay profile sum_a |C_a(tau)|^2 (zero-padded IFFT on a grid), detects the BS if
   its peak clears the noise floor by ``hearability_db`` and by the chi-square(2A) quantile
   that noise alone exceeds with probability ``detection_false_alarm`` over all searched cells
   (delay bins / upsample x Doppler cells, :meth:`ToAEstimator.doppler_cells`: a count that does
   not depend on the scan's step); the floor is exact: sigma^2 sum_k w_k^2 |X_k|^2 per block
   and antenna, with sigma^2 the per-RE noise variance;
4. picks the ToA of a detected BS (an undetected one keeps the scan's Doppler and the strongest
   lag): the strongest peak, or the first local peak above both a noise-derived
   threshold (chi-square with 2A degrees of freedom at ``false_alarm`` per bin and Doppler
   cell) and ``first_path_rel_db`` below the strongest, on a Hann-windowed delay-Doppler
   map maximised over Doppler per delay bin (the paths of one link spread over +-f_D,max, more
   than the frame's Doppler resolution, so one common Doppler could null the first path); the
   first path's own Doppler then replaces the scan's when they are more than a quarter of the
   Doppler resolution apart;
5. refines it below the grid step by parabolic interpolation on exact evaluations of the profile.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.fft as sfft
from scipy.linalg.blas import zherk as _zherk
from scipy.special import chdtri   # chi-square inverse survival function (a ufunc: 40x
                                   # faster than scipy.stats.chi2.isf, same values)

from ..channel import as_slice, kept, kept_by_id, occupancy_groups
from ..shortcuts import reference
from .toa_kernels import antenna_power, cast_blocks, interleave_groups, multiply_into
from ...config.channel import ReceiverConfig

__all__ = ["CrossSpectra", "ToAEstimate", "ToAEstimator"]


#: :func:`as_slice` of the groups' bins by their bytes (a chain's combs are the same at every call)
_SLICES: dict = {}

#: whether groups' bins overlap and cover every bin, by the groups' bins (the same at every
#: call of a chain)
_OVERLAPS: dict = {}


@dataclass(frozen=True, eq=False)
class CrossSpectra:
    """Per-block, per-antenna cross-spectra of a received signal with one replica.

    spectra : [num_ant, num_blocks, num_bins] complex128, S_abk (c_ab(tau) = sum_k S_abk
        e^{j2pi f_k tau}); None when given by ``parts``
    freqs : [num_bins] float64, Hz, integer multiples of ``bin_spacing_hz``
    bin_spacing_hz : float, Hz (the profile is periodic in tau with period 1 / bin_spacing_hz)
    block_times : [num_blocks] float64, s, centre of each block (any common origin)
    ref_power : [num_blocks, num_bins] float64, |X_bk|^2 scaled so that white noise of
        variance sigma^2 per RE gives var c_ab(tau) = sigma^2 sum_k w_k^2 ref_power[b, k]
    band_hz : float, Hz, occupied bandwidth (for the frequency window)
    parts : tuple of (blocks, bins, S[A, len(blocks), len(bins)]) or None: the spectra on the
        replica's occupied bins only (``ref_power > 0``; S = Y X* is zero elsewhere), the
        blocks grouped by the bins they occupy (a comb-6 PRS: 6 groups of 1/6 of the bins)
    """

    spectra: np.ndarray | None
    freqs: np.ndarray
    bin_spacing_hz: float
    block_times: np.ndarray
    ref_power: np.ndarray
    band_hz: float
    parts: tuple | None = None

    def __post_init__(self) -> None:
        if self.spectra is None and self.parts is None:
            raise ValueError("CrossSpectra needs `spectra` or `parts`")

    @property
    def num_ant(self) -> int:
        return (self.spectra if self.spectra is not None else self.parts[0][2]).shape[0]

    @cached_property
    def bin_power(self) -> np.ndarray:
        """[num_bins] float64, ``ref_power`` summed over the blocks (the noise floor of a
        windowed profile is sigma^2 sum_k w_k^2 bin_power[k] per antenna)."""
        return self.ref_power.sum(axis=0)

    @cached_property
    def dense(self) -> np.ndarray:
        """[num_ant, num_blocks, num_bins] complex128, the spectra with their zeros."""
        if self.spectra is not None:
            return self.spectra
        out = np.zeros((self.num_ant,) + self.ref_power.shape, dtype=np.complex128)
        for blocks, bins, part in self.parts:
            out[:, blocks[:, None], bins[None, :]] = part
        return out

    @cached_property
    def occupied(self) -> tuple | None:
        """``parts``, or the dense spectra's occupied entries in the same form (None when every
        block occupies every bin: the dense spectra are all there is)."""
        if self.parts is not None:
            return self.parts
        groups = occupancy_groups(self.ref_power > 0)
        if groups is None:
            return None
        return tuple((b, k, self.spectra[:, b[:, None], k[None, :]]) for b, k in groups)

    @cached_property
    def groups(self) -> tuple:
        """``occupied``, or one group of every block and bin when that is None: what the
        products below loop over (one product per group)."""
        if self.occupied is not None:
            return self.occupied
        b, k = self.spectra.shape[1:]
        return ((np.arange(b), np.arange(k), self.spectra),)

    @cached_property
    def bin_index(self) -> tuple:
        """Per group of :attr:`groups`, its bins as an index: a slice when they are evenly
        spaced (a comb), else the index array (a slice scatters several times faster)."""
        return tuple(kept(_SLICES, bins.tobytes(), lambda: as_slice(bins)) for _, bins, _ in self.groups)

    @cached_property
    def _cover(self) -> tuple:
        """(some bin in more than one group, every bin in a group, :attr:`bin_map`) for
        :attr:`groups`."""
        bins = [b for _, b, _ in self.groups]

        def make():
            cover = np.zeros(self.freqs.size, dtype=np.int64)
            for b in bins:
                cover[b] += 1
            stacked = None
            if len({b.size for b in bins}) == 1:
                stacked = np.stack(bins).astype(np.int64)
                stacked.flags.writeable = False
            return bool(np.any(cover > 1)), bool(np.all(cover > 0)), stacked

        return kept(_OVERLAPS, (self.freqs.size,) + tuple(b.tobytes() for b in bins), make)

    @property
    def bins_overlap(self) -> bool:
        """Some bin belongs to more than one group of :attr:`groups` (blocks with different but
        overlapping occupancy: their products add up on the shared bins)."""
        return self._cover[0]

    @property
    def bins_covered(self) -> bool:
        """Every bin belongs to some group of :attr:`groups` (else some bins stay zero)."""
        return self._cover[1]

    @property
    def stacked_bins(self) -> np.ndarray | None:
        """[G, J] int64, the bins of :attr:`groups` stacked, when the groups are of one size J
        (a comb's); else None."""
        return self._cover[2]

    def combine(self, weights: np.ndarray) -> np.ndarray:
        """sum_b w_b S_abk: [B] -> [A, K] complex128."""
        out = np.zeros((self.num_ant, self.freqs.size), dtype=np.complex128)
        for (blocks, _, part), ix in zip(self.groups, self.bin_index):
            out[:, ix] += (weights[blocks][None, None, :] @ part)[:, 0, :]
        return out

    def at_delay(self, tau: float, e: np.ndarray | None = None) -> np.ndarray:
        """Per-block correlation c_ab(tau) = sum_k S_abk e^{j2pi f_k tau}: [A, B] complex128.

        :param e: [K] complex128, e^{j2pi f_k tau} when the caller has it already
        """
        if e is None:
            e = np.exp(2j * np.pi * self.freqs * tau)
        out = np.zeros((self.num_ant, self.ref_power.shape[0]), dtype=np.complex128)
        for (blocks, _, part), ix in zip(self.groups, self.bin_index):
            out[:, blocks] = (part.reshape(-1, part.shape[-1]) @ e[ix]).reshape(part.shape[:2])
        return out


@dataclass(frozen=True, eq=False)
class ToAEstimate:
    """Timing of one transmitter.

    detected : bool, the peak cleared the hearability threshold
    toa_s : float, s, arrival time relative to the receiver's timing reference (NaN if not detected)
    doppler_hz : float, Hz, estimated Doppler (frequency offset) of the strongest component
    peak_snr_db : float, dB, strongest profile peak over the noise floor
    peak : [num_ant] complex128, per-antenna correlation at (toa, doppler)
    snapshots : [num_ant, num_blocks] complex128, per-block correlation at toa, Doppler-derotated
    noise_var : float, per-RE noise variance used
    """

    detected: bool
    toa_s: float
    doppler_hz: float
    peak_snr_db: float
    peak: np.ndarray
    snapshots: np.ndarray
    noise_var: float


@dataclass(frozen=True, eq=False)
class _LagGrid:
    """The zero-padded delay profile's grid: idx [K] int64, the bins' grid indices; lags [L]
    int64, the searched lag indices; size : int, the grid size; step : float, s, the lag step."""

    idx: np.ndarray
    lags: np.ndarray
    size: int
    step: float


@dataclass(frozen=True, eq=False)
class _Layout:
    """What :class:`ToAEstimator` derives from the bins alone (kept per bin layout, read-only):
    grid : the upsampled profile's :class:`_LagGrid`; scan : the Doppler scan's (no zero
    padding); win : [K] float64, the first-path window; win32 : [K] float32, the same; win2 :
    [K] float64, its square; shifts : [R, K, 3] complex128, e^{j2pi f_k s} for the shifts
    s = -h_r, 0, h_r of the R refinement steps (h_r = step / 4^(r+1))."""

    grid: _LagGrid
    scan: _LagGrid
    win: np.ndarray
    win32: np.ndarray
    win2: np.ndarray
    shifts: np.ndarray


@dataclass(frozen=True, eq=False)
class _DopplerScan:
    """The Doppler scan of step 1: spectra [V, A, K] complex64 (sum_b e^{-j2pi nu t_b} S_abk per
    hypothesis; possibly a view of the thread's transform input, valid within the call),
    hypotheses [V] float64, Hz; reach_s: s, the latest lag at which the scan's delay-Doppler
    power comes within :data:`FIRST_PATH_MAP_REACH_DB` of its peak."""

    spectra: np.ndarray
    hypotheses: np.ndarray
    reach_s: float


@dataclass(frozen=True, eq=False)
class _Derotated:
    """The spectra combined over the blocks at one Doppler: doppler_hz : float, Hz; rot : [B]
    complex128, e^{-j2pi nu t_b}; combined : [A, K] complex128, sum_b rot_b S_abk."""

    doppler_hz: float
    rot: np.ndarray
    combined: np.ndarray


class SingleSpectra:
    """:meth:`CrossSpectra.combine` and :meth:`CrossSpectra.at_delay` from the single-precision
    copies of the spectra that the Doppler scan makes (:meth:`ToAEstimator.doppler_spectra`'s
    ``keep``; the shortcut ``spectra32``): the same sums of the products rounded to complex64,
    half the memory read of the complex128 spectra; results in complex128.

    :param cs: the cross-spectra; parts: per group of ``cs.groups`` [B_g, A, K_g] complex64
    """

    def __init__(self, cs: CrossSpectra, parts: list):
        self.cs, self.parts = cs, parts

    def combine(self, weights: np.ndarray) -> np.ndarray:
        """sum_b w_b S_abk: [B] -> [A, K] complex128 (products in single precision)."""
        cs = self.cs
        out = np.zeros((cs.num_ant, cs.freqs.size), dtype=np.complex128)
        w = weights.astype(np.complex64)
        for (blocks, _, _), ix, q in zip(cs.groups, cs.bin_index, self.parts):
            out[:, ix] += (w[blocks] @ q.reshape(blocks.size, -1)).reshape(q.shape[1:])
        return out

    def at_delay(self, tau: float, e: np.ndarray | None = None) -> np.ndarray:
        """c_ab(tau) = sum_k S_abk e^{j2pi f_k tau}: [A, B] complex128 (products in single
        precision). :param e: [K] complex128, e^{j2pi f_k tau} when the caller has it already"""
        cs = self.cs
        if e is None:
            e = np.exp(2j * np.pi * cs.freqs * tau)
        e = e.astype(np.complex64)
        out = np.zeros((cs.num_ant, cs.ref_power.shape[0]), dtype=np.complex128)
        for (blocks, _, _), ix, q in zip(cs.groups, cs.bin_index, self.parts):
            out[:, blocks] = (q.reshape(-1, q.shape[-1]) @ e[ix]).reshape(q.shape[:2]).T
        return out


#: per-thread transform inputs of :func:`_padded` (a chain may run in several threads of a Dask
#: worker)
_WORK = threading.local()

#: the most inputs :func:`_padded` keeps per thread (a chain uses a handful of shapes)
_PADDED_MAX = 32


def _padded(name: str, shape: tuple, dtype, head: int) -> np.ndarray:
    """A zero-padded transform input of ``shape`` and ``dtype`` kept from call to call: zero
    beyond the first ``head`` entries of the last axis, contents undefined within them.

    Callers write only the head (or zero it before scattering into it) and transform out of
    place, so the padding is zeroed once, when the array is made, instead of at every call (the
    zero-padded profiles are megabytes: 33 Doppler hypotheses x 5 antennas x 1440 or 1024
    lags). One array per (name, shape, dtype, head).
    """
    store = getattr(_WORK, "padded", None)
    if store is None:
        store = _WORK.padded = {}
    dtype = np.dtype(dtype)
    key = (name, tuple(shape), dtype.str, int(head))
    a = store.get(key)
    if a is None:
        if len(store) >= _PADDED_MAX:
            store.clear()
        a = store[key] = np.zeros(shape, dtype=dtype)
    return a


def _is_view(a: np.ndarray, b: np.ndarray) -> bool:
    """``a`` is ``b`` (the same memory, shape and strides): already where it would be copied."""
    return (a.shape == b.shape and a.strides == b.strides
            and a.__array_interface__["data"][0] == b.__array_interface__["data"][0])


def spatial_dof(x: np.ndarray, hermitian: bool = False) -> float:
    """Effective chi-square degrees of freedom of sum_a |x_a|^2 for zero-mean samples x.

    Satterthwaite's two-moment match of sum_i lambda_i chi2(2) / 2, lambda_i the eigenvalues of
    the spatial covariance of ``x``: dof = 2 (sum lambda)^2 / sum lambda^2; 2 A for noise
    independent per antenna, 2 for a field from one direction (a jammer, a relay, a spoofer).

    The covariance R is Hermitian, so sum lambda = tr R and sum lambda^2 = ||R||_F^2: no
    eigendecomposition needed.

    :param x: [num_ant, num_samples] complex, or a sequence of such blocks (their samples
        pooled, as if concatenated)
    :param hermitian: R by BLAS's Hermitian rank-k update (:func:`spatial_covariance_stats`; the
        shortcut ``dofherk``), else by the products ``x x^H`` (the reference)
    :returns: float in [2, 2 num_ant] (2 num_ant without energy)
    """
    return spatial_covariance_stats(x, hermitian)[1]


def spatial_covariance_stats(x: np.ndarray, hermitian: bool = False) -> tuple[float, float]:
    """``(tr R, spatial_dof)`` of the samples ``x`` (as :func:`spatial_dof`), R = sum_n x_n x_n^H
    unscaled: tr R is sum |x|^2 over every antenna and sample.

    ``hermitian``: complex128 blocks through ``zherk`` (one triangle of R, no conjugated copy of
    the samples, half the products), ||R||_F^2 from the diagonal and twice the strict triangle;
    the same sums as the reference's ``x @ x.conj().T`` in another order (rounding only).
    """
    blocks = [x] if isinstance(x, np.ndarray) else list(x)
    a = blocks[0].shape[0]
    if hermitian and all(b.dtype == np.complex128 for b in blocks):
        r = None
        for b in blocks:   # b.T [N, A] (Fortran order for a C-ordered b, no copy); trans=2: b.T^H b.T
            r = (_zherk(1.0, b.T, trans=2) if r is None
                 else _zherk(1.0, b.T, beta=1.0, c=r, trans=2, overwrite_c=1))
        d = r.diagonal().real                        # conj(R)'s upper triangle: the same moduli
        tr = float(d.sum())
        fro = float((d * d).sum()) + 2.0 * float((np.abs(np.triu(r, 1)) ** 2).sum())
    else:
        r = sum(b @ b.conj().T for b in blocks)      # [A, A]; the 1/N scale cancels in the ratio
        tr = float(r.trace().real)
        fro = float((np.abs(r) ** 2).sum())
    if tr <= 0:
        return tr, 2.0 * a
    return tr, float(_clip(2.0 * tr ** 2 / fro, 2.0, 2.0 * a))


def _median(x: np.ndarray) -> float:
    """Median of a 1-D array without NaNs: ``np.median``'s value (the middle element, or the mean
    of the two middle ones) from one partition, without its checks and dispatch."""
    n = x.size
    k = n // 2
    if n % 2:
        return float(np.partition(x, k)[k])
    part = np.partition(x, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2)


def _clip(x, lo, hi):
    """``np.clip`` of a scalar (the same value, NaN kept) without the array machinery."""
    return min(max(x, lo), hi)


def _parabola(ym: float, y0: float, yp: float) -> float:
    """Vertex offset in [-1, 1] of the parabola through (-1, ym), (0, y0), (1, yp)."""
    den = ym - 2.0 * y0 + yp
    if den >= 0 or not np.isfinite(den):
        return 0.0
    return float(_clip(0.5 * (ym - yp) / den, -1.0, 1.0))


#: the Doppler scan's rotations by (hypotheses, block times): one chain's blocks and
#: hypotheses are the same at every point
_ROTATIONS: dict = {}


def _doppler_rotations(nus: np.ndarray, tc: np.ndarray) -> np.ndarray:
    """e^{-j 2 pi nu_v t_b}: [V, B] complex64 (kept, read-only)."""
    def make():
        rot = np.exp(-2j * np.pi * nus[:, None] * tc[None, :]).astype(np.complex64)
        rot.flags.writeable = False
        return rot

    return kept(_ROTATIONS, (nus.tobytes(), tc.tobytes()), make)


#: :func:`_group_rotations` by (rotations, groups' blocks)
_GROUP_ROTATIONS: dict = {}


def _group_rotations(rot: np.ndarray, cs: CrossSpectra) -> tuple:
    """The columns of the Doppler rotations ``rot`` [V, B] of each group of ``cs.groups``,
    [V, B_g] complex64 each (C-contiguous, kept, read-only)."""
    def make():
        out = tuple(np.ascontiguousarray(rot[:, blocks]) for blocks, _, _ in cs.groups)
        for a in out:
            a.flags.writeable = False
        return out

    return kept_by_id(_GROUP_ROTATIONS, (rot,), make,
                      tuple(blocks.tobytes() for blocks, _, _ in cs.groups))


class ZoomPlan:
    """Chirp-z (Bluestein) evaluation of zero-padded profiles on a window of lags.

    c(l) = sum_k x_k e^{j 2 pi p_k l / N} for the M lags l = l0 .. l0 + M - 1 only, with the bins
    at positions p_k in [0, P): by p l = (p^2 + m^2 - (m - p)^2) / 2 (l = l0 + m) it is
    e^{j pi m^2 / N} times the linear convolution of a_p = x_p e^{j 2 pi p l0 / N} e^{j pi p^2 / N}
    with h(d) = e^{-j pi d^2 / N}, d in [-(P - 1), M - 1], done by FFTs of a length L >= P + M - 1
    (Bluestein, IEEE Trans. Audio Electroacoust. 18(4), 1970; Rabiner, Schafer and Rader, "The
    chirp z-transform algorithm", ibid. 17(2), 1969). Two FFTs of L instead of one of N: with the
    searched window a fifth of the period (N = 4096, P = 624, M = 755: L = 1440) about a third
    less work. The factor e^{j pi m^2 / N} has modulus 1 and drops out of |c(l)|^2.

    :param pos: [K] int64, the bins' positions p_k; l0, m: the first lag and the number of lags;
        n: the grid size N; dtype: complex64 or complex128 (the transforms' precision)
    :param size: the length L (default :func:`fft_length` of P + M - 1); every L >= P + M - 1
        gives the same values up to rounding, a shorter one aliases the convolution
    """

    def __init__(self, pos: np.ndarray, l0: int, m: int, n: int, dtype: np.dtype,
                 size: int | None = None):
        p_n = int(pos.max()) + 1
        self.pos, self.m, self.dtype, self.p_n = pos, m, dtype, p_n
        self.size = fft_length(p_n + m - 1) if size is None else int(size)
        if self.size < p_n + m - 1:
            raise ValueError(f"size {self.size} is below P + M - 1 = {p_n + m - 1}")
        self.contiguous = bool(pos[0] == 0 and np.all(np.diff(pos) == 1))

        def chirp(x):   # e^{j pi x^2 / N}, with x^2 reduced mod 2N in integers (exact phase)
            x = np.asarray(x, dtype=np.int64)
            return np.exp(1j * np.pi * ((x * x) % (2 * n)) / n)

        k = pos.astype(np.int64)
        self.pre = (chirp(k) * np.exp(2j * np.pi * ((k * l0) % n) / n)).astype(dtype)   # [K]
        h = np.zeros(self.size, dtype=np.complex128)
        d = np.arange(-(p_n - 1), m)
        h[d % self.size] = np.conj(chirp(d))
        self.filter = sfft.fft(h).astype(dtype)                                        # [L]

    def power(self, g: np.ndarray, win: np.ndarray | None) -> np.ndarray:
        """sum_a |c_a(l)|^2 of g [..., A, K] (times ``win`` [K] per bin): [..., M] float64."""
        pre = self.pre if win is None else self.pre * win
        buf = _padded("zoom", g.shape[:-1] + (self.size,), self.dtype, self.p_n)
        if self.contiguous and np.result_type(g, pre) == g.dtype:
            # NumPy's product (pre cast to g's type as NumPy does), without its dispatch
            # and broadcast over the strided head: multiply_into gives the same bits
            multiply_into(np.ascontiguousarray(g).reshape(-1, g.shape[-1]), pre.astype(g.dtype),
                          buf.reshape(-1, self.size))
        elif self.contiguous:
            np.multiply(g, pre, out=buf[..., :self.pos.size])
        else:
            buf[..., :self.p_n] = 0
            buf[..., self.pos] = g * pre
        x = sfft.fft(buf, axis=-1)                       # out of place: buf's padding stays zero
        x *= self.filter
        y = sfft.ifft(x, axis=-1, overwrite_x=True)
        return summed_power(y, ((0, self.m),))


def fft_length(n: int) -> int:
    """The chirp-z transforms' length for a linear convolution of n outputs: the smallest
    5-smooth length >= n (``scipy.fft.next_fast_len(n, real=True)``).

    Any length >= n gives the same convolution (to rounding); the 5-smooth ones run on
    pocketfft's radix-4, 2, 3 and 5 passes only. ``next_fast_len(n)`` also admits factors 7 and
    11, whose passes cost more per element: for the chain's grid (n = 1378) it picks
    2 3^2 7 11 = 1386, which was measured slower than 2^5 3^2 5 = 1440 (docs/notes/performance-history.md).
    """
    return sfft.next_fast_len(n, real=True)


#: chirp-z plans by (bins, first lag, lags, grid size, dtype)
_ZOOM_PLANS: dict = {}


def zoom_plan(pos: np.ndarray, l0: int, m: int, n: int, dtype: np.dtype) -> ZoomPlan | None:
    """The :class:`ZoomPlan` of these bins and lags (kept), or None when one FFT of the whole
    grid costs less (cost ~ L log2 L per FFT: two of the chirp-z length against one of N)."""
    def make():
        size = fft_length(int(pos.max()) + m)
        cheaper = 2 * size * np.log2(size) < 0.8 * n * np.log2(n)
        return ZoomPlan(pos, l0, m, n, dtype) if cheaper else None

    return kept(_ZOOM_PLANS, (pos.tobytes(), l0, m, n, dtype.str), make)


def summed_power(p: np.ndarray, runs: tuple | None = None) -> np.ndarray:
    """sum_a |p_a|^2 over the antenna axis -2: [..., A, M] complex -> [..., L] float64, on the
    runs ``(start, length)`` of the last axis, concatenated (None: all of it, L = M).

    |p|^2 in p's precision (re^2 + im^2), summed over the antennas in float64: the values of
    ``np.sum(p.real ** 2 + p.imag ** 2, axis=-2, dtype=np.float64)`` bit for bit, by one
    compiled loop (:func:`~veriloc_rt.phy.receiver.toa_kernels.antenna_power`) instead of
    four passes and their temporaries (measured 5x faster on [27, 5, 755] complex64).
    """
    m = p.shape[-1]
    q = np.ascontiguousarray(p).reshape(-1, p.shape[-2], m)
    if runs is None:
        runs = ((0, m),)
    out = np.empty((q.shape[0], sum(n for _, n in runs)))
    at = 0
    for start, n in runs:
        antenna_power(q, start, n, out, at)
        at += n
    return out.reshape(p.shape[:-2] + (at,))


#: Doppler cells per Doppler resolution 1 / T (T: the blocks' time aperture) that the detection
#: thresholds count over the scanned span, whatever the scan's step: the maximum over a finely
#: sampled Doppler axis behaves like the maximum over this many cells per resolution. Counting
#: the scan's hypotheses instead made noise-only false alarms fall with a finer step (0.18 at a
#: 50 Hz step to 0.03 at 6.25 Hz, at a design 0.1); with 4 per resolution they are the design
#: value at every step (tests/unit/phy/receiver/test_toa.py, docs/notes/performance-history.md)
DOPPLER_CELLS_PER_RESOLUTION = 4.0
#: the first path's own Doppler (a parabola on the delay-Doppler map's grid) replaces the scan's
#: (refined on the strongest path's block phases) only when they lie further apart than this
#: share of the Doppler resolution 1 / T (a quarter: 0.9 dB of derotation loss, sinc^2(1/4)):
#: closer, they are the same path's and the scan's is the finer estimate. A rule in scan steps
#: made the fixes depend on the step (docs/notes/performance-history.md)
FIRST_PATH_DOPPLER_TOLERANCE = 0.25
#: the first-path search's delay-Doppler map covers the lags up to the last one at which the
#: Doppler scan's power comes within this many dB of its peak (and up to the strongest lag of the
#: Doppler-compensated profile), plus :data:`FIRST_PATH_MAP_MARGIN_S`; the rest of the search
#: window is not transformed. The first path precedes the strongest, and the map's own strongest
#: cell, the relative threshold's reference, is one of the scan's strong cells: the scan differs
#: from the map by its straddle loss (up to 3.9 dB without zero padding) and its rectangular
#: window (docs/notes/performance-history.md, "The first-path map's lags")
FIRST_PATH_MAP_REACH_DB = 10.0
#: s, the margin past :data:`FIRST_PATH_MAP_REACH_DB`'s last lag
FIRST_PATH_MAP_MARGIN_S = 1e-6
#: the map's lag count is rounded up to a multiple of this (a few transform plans per run)
MAP_LAGS_QUANTUM = 32


class ToAEstimator:
    """Doppler, ToA and hearability of one transmitter from its :class:`CrossSpectra`.

    :param cfg: receiver config (ToA rule, window, thresholds, Doppler scan)
    :param guard_s: negative lags searched (the timing reference's guard), s
    """

    def __init__(self, cfg: ReceiverConfig, guard_s: float = 0.25e-6):
        self.cfg = cfg
        self.guard_s = float(guard_s)
        #: Doppler hypotheses [V] float64, Hz (None without a scan)
        self.hypotheses = (np.arange(-cfg.doppler_max_hz, cfg.doppler_max_hz + 1e-9, cfg.doppler_step_hz)
                           if cfg.doppler_max_hz > 0 else None)
        #: the zero-padded profiles' transform precision: complex64 (shortcut ``toa32``), or
        #: None, the spectra's (complex128: the reference)
        self.profile_dtype = None if reference("toa32") else np.dtype(np.complex64)
        #: the spatial covariance by a Hermitian rank-k update (shortcut ``dofherk``)
        self.hermitian = not reference("dofherk")
        #: the spectra's combinations over blocks and bins from the scan's single-precision
        #: copies (shortcut ``spectra32``)
        self.single_spectra = not reference("spectra32")
        self._layouts: dict = {}

    # -- helpers ---------------------------------------------------------------------------
    def _window(self, cs: CrossSpectra, kind: str) -> np.ndarray:
        if kind == "none":
            return np.ones(cs.freqs.shape)
        x = np.clip(cs.freqs / (cs.band_hz + cs.bin_spacing_hz), -0.5, 0.5)
        return np.cos(np.pi * x) ** 2

    def _grid(self, cs: CrossSpectra, upsample: int) -> _LagGrid:
        """Grid indices of the bins, the searched lag indices, the grid size and the lag step."""
        idx = np.round(cs.freqs / cs.bin_spacing_hz).astype(np.int64)
        span = int(idx.max() - idx.min() + 1)
        n_up = 1 << int(np.ceil(np.log2(max(span, 2))))
        n_up *= upsample
        step = 1.0 / (n_up * cs.bin_spacing_hz)
        lags = np.arange(-int(np.ceil(self.guard_s / step)), int(np.ceil(self.cfg.search_window_s / step)) + 1)
        if lags.size >= n_up:
            raise ValueError("search window exceeds the correlation period 1 / bin spacing")
        for a in (idx, lags):
            a.flags.writeable = False
        return _LagGrid(idx, lags, n_up, step)

    def _layout(self, cs: CrossSpectra) -> _Layout:
        """The grids and the window of these bins (kept: a chain's bins are the same at every
        call)."""
        def make():
            win = (self._window(cs, self.cfg.first_path_window) if self.cfg.toa_method != "strongest"
                   else np.ones(cs.freqs.shape))
            grid = self._grid(cs, self.cfg.upsample)
            h = grid.step / 4.0 ** np.arange(1, self.cfg.refine_steps + 1)              # [R], s
            shifts = np.exp(2j * np.pi * cs.freqs[None, :, None]
                            * (h[:, None, None] * np.array([-1.0, 0.0, 1.0])))          # [R, K, 3]
            arrays = (win, win.astype(np.float32), win ** 2, shifts)
            for a in arrays:
                a.flags.writeable = False
            return _Layout(grid, self._grid(cs, 1), *arrays)

        return kept(self._layouts, (cs.freqs.tobytes(), cs.bin_spacing_hz, cs.band_hz), make)

    @staticmethod
    def lag_power(g: np.ndarray, idx: np.ndarray, lags: np.ndarray, n_up: int,
                  win: np.ndarray | None = None, dtype=None) -> np.ndarray:
        """Antenna-summed power of the profiles on the lag grid, sum_a |c_a(tau)|^2:
        [..., num_ant, num_bins] -> [..., num_lags] float64 (transform in g's precision, or in
        ``dtype``'s: complex64 or complex128).

        Only the power is used, so the bins are transformed from the lowest one at index 0: that
        multiplies every profile by one phase ramp over the lags, invisible in |.|^2, and for
        contiguous bins (the frequency front end) the input is the bins followed by zeros. A
        contiguous window of lags short enough goes through the chirp-z plan
        (:func:`zoom_plan`), else one FFT of the whole grid.

        :param win: [num_bins] real, a per-bin window applied on the way into the FFT's buffer
            (the same values as transforming ``g * win``, without the product's own array)

        ``g`` may already be the head of the zero-padded input (:meth:`padded_input`, which
        :meth:`doppler_spectra` can write into): it is then transformed where it is.
        """
        if dtype is None:
            dtype = np.complex64 if g.dtype == np.complex64 else np.complex128
        pos = idx - idx.min()
        plan = zoom_plan(pos, int(lags[0]), lags.size, n_up, np.dtype(dtype))
        if plan is not None and lags[-1] - lags[0] == lags.size - 1:
            return plan.power(g, win)
        buf = _padded("profile", g.shape[:-1] + (n_up,), dtype, int(pos.max()) + 1)
        if pos[-1] == pos.size - 1 and np.all(np.diff(pos) == 1):
            head = buf[..., :pos.size]
            if win is not None:
                np.multiply(g, win, out=head)
            elif not _is_view(g, head):
                head[...] = g
        else:
            buf[..., :int(pos.max()) + 1] = 0
            buf[..., pos] = g if win is None else g * win
        p = sfft.ifft(buf, axis=-1, norm="forward")      # out of place: buf's padding stays zero
        lo, hi = -int(lags[0]), int(lags[-1]) + 1
        if not (0 <= lo and hi <= n_up - lo and lags.size == lo + hi):   # not one wrapped run
            return summed_power(p[..., lags % n_up])
        # the lags -lo..hi-1 are two runs of the FFT's output: read in place, no gather
        return summed_power(p, ((n_up - lo, lo), (0, hi)))

    @staticmethod
    def padded_input(lead: tuple, idx: np.ndarray, n_up: int, dtype) -> np.ndarray | None:
        """The zero-padded input [*lead, n_up] of :meth:`lag_power`'s full-grid transform when
        the bins (grid indices ``idx`` [K]) are contiguous, else None: kept per thread, zero
        beyond the first K entries, contents undefined within them."""
        pos = idx - idx.min()
        if not (pos[-1] == pos.size - 1 and np.all(np.diff(pos) == 1)):
            return None
        return _padded("profile", tuple(lead) + (n_up,), dtype, pos.size)

    @staticmethod
    def doppler_spectra(cs: CrossSpectra, nus: np.ndarray, tc: np.ndarray,
                        out: np.ndarray | None = None, keep: list | None = None) -> np.ndarray:
        """sum_b e^{-j2pi nu t_b} S_abk for every hypothesis nu: [V, A, K] complex64.

        Single precision: the maps built from it only rank hypotheses and cells against
        thresholds (relative error ~1e-7, far below the noise); the ToA itself is refined on
        exact double-precision evaluations. Measured 2x faster than double on the chain
        (benchmarks/bench_chain.py). A per-bin window w_k commutes with the sum over blocks, so
        one product serves the windowed map too. On the occupied parts (``cs.groups``), one
        product per group of blocks sharing their bins: a comb-6 PRS needs 1/6 of the dense
        product's work (summing block by block instead was measured 6x slower). Groups whose
        bins overlap add up on the shared bins; disjoint ones (a comb) are written in place.

        :param out: [V, A, K] complex64 to write into (e.g. the head of :meth:`padded_input`),
            else a new array
        :param keep: a list to append each group's single-precision spectra to, [B_g, A, K_g]
            complex64 in the order of ``cs.groups`` (what :class:`SingleSpectra` reads)
        """
        rot = _doppler_rotations(nus, tc)                                             # [V, B]
        a_ = cs.num_ant
        # groups of one size (a comb's): the products stacked, then written into ``out`` row
        # by row (scattering group by group made one strided pass over ``out`` per group)
        bins_g = cs.stacked_bins
        if out is None:
            out = np.zeros((nus.size, a_, cs.freqs.size), dtype=np.complex64)
        elif bins_g is None and (cs.bins_overlap or not cs.bins_covered):
            out[...] = 0
        stack = (None if bins_g is None else
                 np.empty((len(cs.groups), nus.size, a_, bins_g.shape[1]), dtype=np.complex64))
        for g, ((blocks, bins, part), ix, rot_g) in enumerate(zip(cs.groups, cs.bin_index,
                                                                  _group_rotations(rot, cs))):
            q = np.empty((blocks.size, a_, bins.size), dtype=np.complex64)   # [B_g, A, K_g]
            cast_blocks(np.ascontiguousarray(part), q)                       # cast and reorder in one pass
            if keep is not None:
                keep.append(q)
            if stack is not None:
                np.matmul(rot_g, q.reshape(blocks.size, -1), out=stack[g].reshape(nus.size, -1))
                continue
            prod = (rot_g @ q.reshape(blocks.size, -1)).reshape(-1, a_, bins.size)
            if cs.bins_overlap:
                out[:, :, ix] += prod
            else:
                out[:, :, ix] = prod
        if stack is not None:
            interleave_groups(stack, bins_g, out, cs.bins_overlap or not cs.bins_covered,
                              cs.bins_overlap)
        return out

    def doppler_cells(self, tc: np.ndarray) -> float:
        """Doppler cells the thresholds count: 1 + span x T x :data:`DOPPLER_CELLS_PER_RESOLUTION`
        (span: the scanned hypotheses' extent, Hz; T: the blocks' time aperture, s), 1 without a
        scan. Independent of the step: a finer step resolves the same noise maximum, it does not
        add independent cells.

        :param tc: [B] float64, s, the block times
        """
        if self.hypotheses is None or tc.size < 2:
            return 1.0
        span = float(self.hypotheses[-1] - self.hypotheses[0])
        return 1.0 + span * float(tc.max() - tc.min()) * DOPPLER_CELLS_PER_RESOLUTION

    @staticmethod
    def doppler_tolerance_hz(tc: np.ndarray) -> float:
        """How far the first path's Doppler must lie from the scan's to replace it, Hz:
        :data:`FIRST_PATH_DOPPLER_TOLERANCE` / T (T: the blocks' time aperture; infinite for one
        block, which resolves no Doppler).

        :param tc: [B] float64, s, the block times
        """
        aperture = float(tc.max() - tc.min()) if tc.size > 1 else 0.0
        return FIRST_PATH_DOPPLER_TOLERANCE / aperture if aperture > 0 else np.inf

    @staticmethod
    def map_lags(m_rect: np.ndarray, lags: np.ndarray, step: float, reach_s: float) -> int:
        """How many of the search window's first lags the first-path map covers: up to the
        strongest lag of ``m_rect`` [L] (the Doppler-compensated profile's power on ``lags``, lag
        indices of spacing ``step``, s) or the scan's reach ``reach_s`` (s), whichever is later,
        plus :data:`FIRST_PATH_MAP_MARGIN_S`, rounded up to a multiple of
        :data:`MAP_LAGS_QUANTUM`, at most L."""
        if not np.isfinite(reach_s):
            return m_rect.size
        last = max(int(m_rect.argmax()), int(np.ceil(reach_s / step)) - int(lags[0]))
        need = last + 1 + int(np.ceil(FIRST_PATH_MAP_MARGIN_S / step))
        return min(m_rect.size, -(-need // MAP_LAGS_QUANTUM) * MAP_LAGS_QUANTUM)

    @staticmethod
    def _reach(smap: np.ndarray, layout: _Layout) -> float:
        """The latest lag, s, at which the Doppler scan's power ``smap`` [V, L1] comes within
        :data:`FIRST_PATH_MAP_REACH_DB` of its peak (inf without power)."""
        per_lag = smap.max(axis=0)
        strong = np.flatnonzero(per_lag >= per_lag.max() * 10 ** (-FIRST_PATH_MAP_REACH_DB / 10))
        return float(layout.scan.lags[strong[-1]] * layout.scan.step) if strong.size else np.inf

    def _first_crossing(self, metric: np.ndarray, floor: float, n_cells: float, dof: float) -> int:
        """Index of the first local peak above the noise and relative thresholds.

        The noise threshold is the chi-square(dof) quantile at ``false_alarm`` per bin,
        divided over the ``n_cells`` Doppler cells each bin is the maximum of.
        """
        gamma = chdtri(dof, self.cfg.false_alarm / n_cells) / dof
        thr = max(gamma * floor, metric.max() * 10 ** (-self.cfg.first_path_rel_db / 10))
        above = np.flatnonzero(metric >= thr)
        i = int(above[0]) if above.size else int(metric.argmax())
        while i + 1 < metric.size and metric[i + 1] > metric[i]:
            i += 1
        return i

    # -- main ------------------------------------------------------------------------------
    def __call__(self, cs: CrossSpectra, noise_var: float, noise_dof: float | None = None) -> ToAEstimate:
        """Estimate Doppler and ToA.

        :param noise_var: per-RE noise variance (>= 0), averaged over the antennas
        :param noise_dof: chi-square degrees of freedom of the antenna-summed noise power
            (:func:`~veriloc_rt.phy.receiver.sync.noise_dof`); None: 2 A, noise independent per
            antenna. Spatially coherent noise (jammer, relay) needs fewer, i.e. higher
            thresholds.
        """
        cfg = self.cfg
        t = cs.block_times
        a_n = cs.num_ant
        dof = float(2 * a_n if noise_dof is None else _clip(float(noise_dof), 2.0, 2 * a_n))
        layout = self._layout(cs)
        grid = layout.grid
        idx, lags, n_up, step = grid.idx, grid.lags, grid.size, grid.step
        tc = t - t.mean()
        # 1. Doppler scan on the unwindowed metric (on the grid without zero padding: the
        #    straddle loss is common to every Doppler hypothesis)
        if cfg.doppler_max_hz > 0:
            nus = self.hypotheses
            idx1, lags1, n1 = layout.scan.idx, layout.scan.lags, layout.scan.size
            # contiguous bins: the spectra written straight into the scan transform's input
            pad = self.padded_input((nus.size, a_n), idx1, n1, np.complex64)
            kept32 = [] if self.single_spectra else None
            g_nu = self.doppler_spectra(cs, nus, tc, None if pad is None else pad[..., :idx1.size],
                                        kept32)
            src = cs if kept32 is None else SingleSpectra(cs, kept32)   # combine, at_delay
            smap = self.lag_power(g_nu, idx1, lags1, n1)                             # [V, L1]
            metric = smap.max(axis=-1)
            i = int(metric.argmax())
            nu = float(nus[i])
            if 0 < i < nus.size - 1:
                nu += cfg.doppler_step_hz * _parabola(*metric[i - 1:i + 2])
        else:
            nu, g_nu, nus, smap, src = 0.0, None, None, None, cs
        # 2. residual phase correction from the per-block peaks
        rot = np.exp(-2j * np.pi * nu * tc)
        g = src.combine(rot)
        pd = self.profile_dtype
        m_rect = self.lag_power(g, idx, lags, n_up, dtype=pd)
        tau_pk = float(lags[int(m_rect.argmax())] * step)
        x = src.at_delay(tau_pk) * rot                                              # [A, B]
        ref = x.sum(axis=1)
        z = (x * ref.conj()[:, None]).sum(axis=0)                                # [B]
        w = np.abs(z)
        if cfg.doppler_max_hz > 0 and w.sum() > 0:
            ph = np.angle(z)
            tw = (w * tc).sum() / w.sum()
            slope = (w * (tc - tw) * ph).sum() / max((w * (tc - tw) ** 2).sum(), 1e-30)
            dnu = slope / (2 * np.pi)
            if abs(dnu) <= cfg.doppler_step_hz:
                nu += dnu
                rot = np.exp(-2j * np.pi * nu * tc)
                g = src.combine(rot)
                m_rect = self.lag_power(g, idx, lags, n_up, dtype=pd)
        # 3. detection against the exact noise floor
        # the floor: the thermal one from ``noise_var`` (free symbols), or, when larger, a CFAR
        # estimate from the median of the delay profile. Interference confined to the PRS REs
        # (a spoofer's standard PRS against an encrypted replica, a relay) is absent from the
        # free symbols but spreads over every lag of the profile like noise; its spatial
        # structure sets the degrees of freedom (min with the caller's free-symbol estimate)
        dof = min(dof, spatial_dof([q.reshape(a_n, -1) for _, _, q in cs.groups], self.hermitian))
        nv = max(float(noise_var), 0.0)
        sum_ref = float(cs.bin_power.sum())
        floor_rect = a_n * nv * sum_ref
        cfar = _median(m_rect) * dof / chdtri(dof, 0.5)
        if cfar > floor_rect and sum_ref > 0:
            floor_rect, nv = cfar, cfar / (a_n * sum_ref)
        peak = float(m_rect.max())
        tiny = 1e-30 + 1e-15 * peak
        snr_db = 10 * np.log10(peak / max(floor_rect, tiny)) if peak > 0 else -np.inf
        n_cells = max(lags.size / cfg.upsample, 1.0) * self.doppler_cells(tc)
        gamma_det = chdtri(dof, cfg.detection_false_alarm / n_cells) / dof
        detected = bool(snr_db >= max(cfg.hearability_db, 10 * np.log10(gamma_det)))
        if detected:
            scan = _DopplerScan(g_nu, nus, self._reach(smap, layout)) if smap is not None else None
            tau, d = self._pick(cs, layout, m_rect, scan, _Derotated(nu, rot, g), tc, nv, dof, src)
            nu, rot, g = d.doppler_hz, d.rot, d.combined
        else:   # no ToA to pick: the peak and snapshots at the strongest lag
            tau = float(lags[int(m_rect.argmax())] * step)
        e = np.exp(2j * np.pi * cs.freqs * tau)              # [K], the exact profile's phase ramp
        return ToAEstimate(detected=detected, toa_s=float(tau) if detected else float("nan"),
                           doppler_hz=float(nu), peak_snr_db=float(snr_db),
                           peak=g @ e, snapshots=src.at_delay(tau, e) * rot, noise_var=nv)

    def _pick(self, cs: CrossSpectra, layout: _Layout, m_rect: np.ndarray, scan: _DopplerScan | None,
              start: _Derotated, tc: np.ndarray, nv: float, dof: float,
              src: "CrossSpectra | SingleSpectra | None" = None) -> tuple[float, _Derotated]:
        """Steps 4 and 5 for a detected BS: the ToA, and the derotation (Doppler, block phases,
        combined spectra), ``start`` or, when the first path's own Doppler replaces the scan's,
        the first path's.

        :param layout: the bins' grids and window; m_rect: [L] float64, the zero-padded
            profile's unwindowed power
        :param scan: the Doppler scan (None without one)
        :param tc: [B] float64, s, block times about their mean; nv: per-RE noise variance;
            dof: the noise's chi-square degrees of freedom; src: what combines the spectra
            over the blocks (``cs``, or its single-precision copies: ``spectra32``; None: ``cs``)
        """
        cfg = self.cfg
        a_n = cs.num_ant
        idx, lags, n_up, step = layout.grid.idx, layout.grid.lags, layout.grid.size, layout.grid.step
        nu, rot, g = start.doppler_hz, start.rot, start.combined
        g_nu, nus = (scan.spectra, scan.hypotheses) if scan is not None else (None, None)
        # 4. ToA rule
        win = layout.win                                        # [K], ones for "strongest"
        if cfg.toa_method == "strongest":
            metric = m_rect
            i = int(metric.argmax())
        else:
            floor = a_n * nv * float(cs.bin_power @ layout.win2)
            if cfg.doppler_max_hz > 0:
                # delay-Doppler map (on the zero-padded grid: a coarse one was measured to lose
                # accuracy on UMa fast fading, p50 12.6 -> 17.8 m): paths of one link can
                # differ in Doppler by 2 f_D,max, more than the frame's 100 Hz resolution, and a
                # single coherent Doppler can null the first path; each delay bin takes its best
                # Doppler hypothesis
                # the first path precedes the strongest: the map (and the windowed profile the
                # first path's peak is taken on) end a margin past it
                idx1, n1 = idx, n_up
                lags1 = lags[:self.map_lags(m_rect, lags, step, scan.reach_s)]
                dmap = self.lag_power(g_nu, idx1, lags1, n1, layout.win32)  # [V, L1]
                coarse = dmap.max(axis=0)
                i1 = self._first_crossing(coarse, floor, self.doppler_cells(tc), dof)
                col = dmap[:, i1]
                v = int(col.argmax())
                nu_fp = float(nus[v])
                if 0 < v < nus.size - 1:
                    nu_fp += cfg.doppler_step_hz * _parabola(*col[v - 1:v + 2])
                if abs(nu_fp - nu) > self.doppler_tolerance_hz(tc):   # the first path's own Doppler
                    nu = nu_fp
                    rot = np.exp(-2j * np.pi * nu * tc)
                    g = (cs if src is None else src).combine(rot)
                metric = self.lag_power(g, idx, lags1, n_up, win, self.profile_dtype)   # i1's peak
                tau1 = lags1[i1] / (n1 * cs.bin_spacing_hz)
                i = int(_clip(round(tau1 / step) - lags[0], 0, metric.size - 1))
                while 0 < i < metric.size - 1 and (metric[i + 1] > metric[i] or metric[i - 1] > metric[i]):
                    i += 1 if metric[i + 1] > metric[i] else -1
            else:
                metric = self.lag_power(g * win, idx, lags, n_up, dtype=self.profile_dtype)
                i = self._first_crossing(metric, floor, 1, dof)
        # 5. sub-sample refinement
        if 0 < i < metric.size - 1:
            tau = (lags[i] + _parabola(*metric[i - 1:i + 2])) * step
        else:
            tau = lags[i] * step
        # the profile sum_a |c_a(tau + s)|^2 at s = -h, 0, h is sum_a |sum_k u_ak e^{j2pi f_k s}|^2
        # with u = g w e^{j2pi f tau}: one exp and one product [A, K] @ [K, 3] per step
        gw = g * win
        h = step / 4
        for shift in layout.shifts:                                                # [K, 3]
            c = (gw * np.exp(2j * np.pi * cs.freqs * tau)) @ shift                 # [A, 3]
            vals = summed_power(c)                                                 # [3]
            tau += h * _parabola(*vals)
            h /= 4
        return tau, _Derotated(nu, rot, g)
