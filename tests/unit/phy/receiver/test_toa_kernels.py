"""The ToA search's compiled kernels (veriloc_rt.phy.receiver.toa_kernels) against the NumPy code
they replace.

Kernels that replace NumPy code outright must give its bits: compared with ``np.array_equal``
on arrays of the paper config's shapes and of the chain's value ranges (powers from 1e-16 to 1e6
of the grid's unit). The shortcut's kernels (``jittoa``) are compared with a named tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from veriloc_rt.phy.receiver import toa_kernels as K

#: the paper config's delay-Doppler map: 27 Doppler hypotheses x 5 antennas, a chirp-z length
#: of 1440 of which 755 lags are kept; the scan's full grid of 1024
SHAPES = ((27, 5, 1440), (27, 5, 1024), (1, 5, 1440), (3, 1, 40))


def _field(rng, shape, dtype):
    """Complex values spread over 22 decades of power (the grid's physical units), some
    exactly zero (bins no group occupies)."""
    scale = 10.0 ** rng.uniform(-8, 3, shape)
    x = scale * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    x[..., ::97] = 0
    return x.astype(dtype)


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_antenna_power_is_numpys_sum_of_squares_bit_for_bit(dtype):
    """antenna_power on runs of the last axis (all of it; a head; the two wrapped runs of a
    delay profile) against np.sum(q.real ** 2 + q.imag ** 2, axis=-2, dtype=float64) on those
    runs: equal to the bit (the same squares in q's precision, the antennas added in order)."""
    rng = np.random.default_rng(7)
    for shape in SHAPES:
        q = _field(rng, shape, dtype)
        m = shape[-1]
        want_all = np.sum(q.real ** 2 + q.imag ** 2, axis=-2, dtype=np.float64)
        for runs in (((0, m),), ((0, min(755, m)),), ((m - 4, 4), (0, min(186, m - 4)))):
            want = np.concatenate([want_all[:, s:s + n] for s, n in runs], axis=-1)
            out = np.full(want.shape, np.nan)
            at = 0
            for s, n in runs:
                K.antenna_power(q, s, n, out, at)
                at += n
            assert np.array_equal(out, want)


def test_antenna_power_of_the_estimator_keeps_the_shape():
    """toa.summed_power on [A, L] and [V, A, L] arrays (C-contiguous or a view) and on runs:
    NumPy's values, the antenna axis removed."""
    from veriloc_rt.phy.receiver.toa import summed_power

    rng = np.random.default_rng(8)
    q = _field(rng, (5, 3), np.complex128)
    assert np.array_equal(summed_power(q), np.sum(q.real ** 2 + q.imag ** 2, axis=0))
    p = _field(rng, (27, 5, 64), np.complex64)
    want = np.sum(p.real ** 2 + p.imag ** 2, axis=-2, dtype=np.float64)
    assert np.array_equal(summed_power(p[..., :40]), want[:, :40])
    got = summed_power(p, ((60, 4), (0, 30)))
    assert got.shape == (27, 34)
    assert np.array_equal(got, np.concatenate([want[:, 60:], want[:, :30]], axis=-1))


def _doppler_spectra_numpy(cs, nus, tc):
    """The Doppler scan's product as written in NumPy before the kernels (the reference):
    each group cast and reordered by NumPy, multiplied, scattered into its bins (added where
    groups overlap)."""
    rot = np.exp(-2j * np.pi * nus[:, None] * tc[None, :]).astype(np.complex64)
    out = np.zeros((nus.size, cs.num_ant, cs.freqs.size), dtype=np.complex64)
    keep = []
    for (blocks, bins, part), ix in zip(cs.groups, cs.bin_index):
        q = np.empty((blocks.size, cs.num_ant, bins.size), dtype=np.complex64)
        q[...] = part.transpose(1, 0, 2)
        keep.append(q)
        prod = (rot[:, blocks] @ q.reshape(blocks.size, -1)).reshape(-1, cs.num_ant, bins.size)
        if cs.bins_overlap:
            out[:, :, ix] += prod
        else:
            out[:, :, ix] = prod
    return out, keep


def _spectra(rng, groups, k_n, a_n=5):
    """CrossSpectra on parts: ``groups`` a list of (blocks, bins)."""
    from veriloc_rt.phy.receiver.toa import CrossSpectra

    b_n = 1 + max(int(b.max()) for b, _ in groups)
    ref = np.zeros((b_n, k_n))
    parts = []
    for blocks, bins in groups:
        ref[np.ix_(blocks, bins)] = 1.0
        parts.append((blocks, bins, _field(rng, (a_n, blocks.size, bins.size), np.complex128)))
    return CrossSpectra(None, (np.arange(k_n) - k_n // 2) * 15e3, 15e3,
                        np.arange(b_n) * 71.4e-6, ref, k_n * 15e3, tuple(parts))


@pytest.mark.parametrize("layout", ["comb6", "comb6_uncovered", "overlapping", "unequal", "one_group"])
def test_doppler_spectra_is_the_numpy_product_bit_for_bit(layout):
    """The Doppler scan's spectra and the single-precision copies it keeps (cast_blocks,
    interleave_groups) against the NumPy code they replace, bit for bit, for the paper
    config's comb-6 PRS (6 groups of 20 blocks x 104 of 624 bins), a comb missing one group's
    bins (zeros there), groups whose bins overlap (added), groups of unequal sizes (the NumPy
    scatter) and one dense group; written into a fresh array and into the head of the scan's
    zero-padded buffer."""
    from veriloc_rt.phy.receiver.toa import ToAEstimator

    rng = np.random.default_rng(11)
    blocks = [np.arange(g, 120, 6) for g in range(6)]
    if layout == "comb6":
        groups = [(blocks[g], np.arange((g * 5) % 6, 624, 6)) for g in range(6)]
    elif layout == "comb6_uncovered":
        groups = [(blocks[g], np.arange(g, 624, 6)) for g in range(5)]
    elif layout == "overlapping":
        groups = [(blocks[0], np.arange(0, 300)), (blocks[1], np.arange(200, 500)),
                  (blocks[2], np.arange(324, 624))]
    elif layout == "unequal":
        groups = [(blocks[0], np.arange(0, 300)), (blocks[1], np.arange(300, 624))]
    else:
        groups = [(np.arange(40), np.arange(156))]
    k_n = 156 if layout == "one_group" else 624
    cs = _spectra(rng, groups, k_n)
    nus = np.arange(-400.0, 401.0, 25.0)
    tc = cs.block_times - cs.block_times.mean()
    want, want_keep = _doppler_spectra_numpy(cs, nus, tc)
    keep = []
    got = ToAEstimator.doppler_spectra(cs, nus, tc, None, keep)
    assert np.array_equal(got, want)
    assert len(keep) == len(want_keep)
    assert all(np.array_equal(a, b) for a, b in zip(keep, want_keep))
    pad = np.full((nus.size, 5, 1024), np.nan + 0j, dtype=np.complex64)
    pad[..., k_n:] = 0
    ToAEstimator.doppler_spectra(cs, nus, tc, pad[..., :k_n])
    assert np.array_equal(pad[..., :k_n], want) and not pad[..., k_n:].any()
