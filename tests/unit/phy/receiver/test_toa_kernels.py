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


@pytest.mark.parametrize("dtypes", [(np.complex64, np.complex64, np.complex64),
                                    (np.complex128, np.complex64, np.complex64),
                                    (np.complex128, np.complex128, np.complex128)])
def test_multiply_into_is_numpys_complex_product_bit_for_bit(dtypes):
    """multiply_into against np.multiply(g, pre, out=buf[:, :K]) (the chirp-z plan's fill: g
    [N, K] times the pre-multiplier [K] into the head of a longer buffer), for the chain's
    type combinations (pre cast to g's type first, as NumPy's type resolution does) and
    lengths with and without a SIMD remainder: equal to the bit."""
    g_t, pre_t, out_t = dtypes
    rng = np.random.default_rng(13)
    for k in (624, 103, 7, 1):
        g = _field(rng, (135, k), g_t)
        pre = np.exp(2j * np.pi * rng.random(k)).astype(pre_t) * rng.uniform(0.1, 1.0, k).astype(pre_t)
        want = np.zeros((135, 1440), out_t)
        np.multiply(g, pre, out=want[:, :k])
        got = np.zeros((135, 1440), out_t)
        K.multiply_into(g, pre.astype(g_t), got)
        assert np.array_equal(got, want)
    if out_t is not g_t:
        return   # rounded to single precision, a double product's last bits rarely show
    # a loop's separately rounded products are not NumPy's where it fuses: the rule matters
    if K.numpy_product_rule(g_t) is not True:
        return
    g = _field(rng, (135, 624), g_t)
    p = np.exp(2j * np.pi * rng.random(624)).astype(g_t)
    got = np.zeros((135, 624), out_t)
    K.multiply_into(g, p, got)
    unfused = ((g.real * p.real - g.imag * p.imag) + 1j * (g.real * p.imag + g.imag * p.real)).astype(out_t)
    assert not np.array_equal(got, unfused)


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_the_probed_product_rule_is_numpys_on_other_values(dtype):
    """numpy_product_rule's verdict, from its probe of 64 products, predicts NumPy's bits on
    10^4 other products (the rule's formula written out with fma's exact Python body, or with
    separately rounded products)."""
    rule = K.numpy_product_rule(dtype)
    assert rule is not None   # this machine's NumPy follows one of the two rules
    rng = np.random.default_rng(23)
    t = np.dtype(dtype).type(0).real.dtype.type
    a = (rng.standard_normal(2000) + 1j * rng.standard_normal(2000)).astype(dtype)
    b = (rng.standard_normal(2000) + 1j * rng.standard_normal(2000)).astype(dtype)
    if rule:
        want = [complex(K.fma(x.real, y.real, t(-(x.imag * y.imag))),
                        K.fma(x.real, y.imag, t(x.imag * y.real))) for x, y in zip(a, b)]
    else:
        want = [complex(t(x.real * y.real) - t(x.imag * y.imag),
                        t(x.real * y.imag) + t(x.imag * y.real)) for x, y in zip(a, b)]
    assert np.array_equal(a * b, np.array(want, dtype=dtype))


def test_fma_rounds_once():
    """fma's Python body (the kernels' code under NUMBA_DISABLE_JIT; compiled, it is checked
    through multiply_into against NumPy above) against the exact value a b + c rounded once:
    Fraction arithmetic is exact and float() of a Fraction rounds to nearest, so for float64
    the two agree exactly; for float32 no neighbour is nearer the exact value. The cases
    include cancellations where a separately rounded product differs (the point of fma)."""
    from fractions import Fraction

    rng = np.random.default_rng(17)
    for t in (np.float64, np.float32):
        a, b = rng.standard_normal(200).astype(t), rng.standard_normal(200).astype(t)
        c = (-(a * b) * (1 + rng.uniform(-1e-6, 1e-6, 200))).astype(t)   # cancellation
        for i in range(200):
            exact = Fraction(float(a[i])) * Fraction(float(b[i])) + Fraction(float(c[i]))
            got = K.fma(a[i], b[i], c[i])
            assert type(got) is t
            if t is np.float64:
                assert got == float(exact)
            else:
                lo, hi = np.nextafter(got, t(-np.inf)), np.nextafter(got, t(np.inf))
                d = abs(Fraction(float(got)) - exact)
                assert d <= abs(Fraction(float(lo)) - exact) and d <= abs(Fraction(float(hi)) - exact)
        unfused = a * b + c
        fused = np.array([K.fma(x, y, z) for x, y, z in zip(a, b, c)])
        assert np.any(fused != unfused)


def test_zoom_plan_power_is_the_numpy_evaluation_bit_for_bit():
    """ZoomPlan.power on the paper config's delay-Doppler map (27 x 5 x 624 complex64 spectra,
    the Hann window, lags -16..(-16 + 256)) and on one Doppler's double-precision spectra
    transformed in single precision (the toa32 profile), against the NumPy code the kernels
    replace (fill by np.multiply, transforms, filter, power by NumPy's reduction): equal."""
    import scipy.fft as sfft

    from veriloc_rt.phy.receiver.toa import zoom_plan

    rng = np.random.default_rng(19)
    pos = np.arange(624)
    win = (np.cos(np.pi * np.linspace(-0.49, 0.49, 624)) ** 2)
    for g, w, m in ((_field(rng, (27, 5, 624), np.complex64), win.astype(np.float32), 256),
                    (_field(rng, (5, 624), np.complex128), win, 755),
                    (_field(rng, (5, 624), np.complex128), None, 755)):
        plan = zoom_plan(pos, -16, m, 4096, np.dtype(np.complex64))
        pre = plan.pre if w is None else plan.pre * w
        buf = np.zeros(g.shape[:-1] + (plan.size,), plan.dtype)
        np.multiply(g, pre, out=buf[..., :624])
        x = sfft.fft(buf, axis=-1)
        x *= plan.filter
        y = sfft.ifft(x, axis=-1, overwrite_x=True)[..., :m]
        want = np.sum(y.real ** 2 + y.imag ** 2, axis=-2, dtype=np.float64)
        assert np.array_equal(plan.power(g, w), want)
