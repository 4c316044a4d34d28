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
