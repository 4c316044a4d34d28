"""Compiled kernels of the ToA search (:mod:`~veriloc_rt.phy.receiver.toa`): fused loops in place
of sequences of NumPy passes (:mod:`~veriloc_rt.phy.jit`, compiled at their first call).

Each kernel takes C-contiguous arrays of fixed dimensions (a caller reshapes), so that a chain
compiles few signatures. The kernels that give the NumPy code's bits (same operations, same
order, same precision) replace it outright; the others belong to the shortcut ``jittoa``
(:mod:`~veriloc_rt.phy.shortcuts`) and the NumPy code stays their reference path.
"""

from __future__ import annotations

import numpy as np

from ..jit import kernel

__all__ = ["antenna_power"]


@kernel
def antenna_power(q, start, length, out, out_start):
    """out[n, out_start + l] = sum_a |q[n, a, start + l]|^2 for l < length.

    :param q: [N, A, M] complex64 or complex128, C-contiguous
    :param out: [N, P] float64, C-contiguous

    Bit for bit NumPy's ``np.sum(q.real ** 2 + q.imag ** 2, axis=-2, dtype=np.float64)``: the
    squares and their sum in q's precision, the antennas added in float64 in their order (NumPy
    reduces a non-innermost axis row by row, in order).
    """
    n_n, a_n = q.shape[0], q.shape[1]
    for n in range(n_n):
        row = out[n, out_start:out_start + length]
        src = q[n, 0, start:start + length]
        for i in range(length):
            re = src[i].real
            im = src[i].imag
            row[i] = np.float64(re * re + im * im)
        for a in range(1, a_n):
            src = q[n, a, start:start + length]
            for i in range(length):
                re = src[i].real
                im = src[i].imag
                row[i] += np.float64(re * re + im * im)
