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

__all__ = ["antenna_power", "cast_blocks", "interleave_groups"]


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


@kernel
def cast_blocks(part, q):
    """q[b, a, k] = complex64(part[a, b, k]): the spectra of a group of blocks reordered
    block-major and rounded to single precision (NumPy's cast: each part rounded to nearest).

    :param part: [A, B, K] complex128, C-contiguous; q: [B, A, K] complex64, C-contiguous
    """
    a_n, b_n, k_n = part.shape
    for b in range(b_n):
        for a in range(a_n):
            src = part[a, b]
            dst = q[b, a]
            for k in range(k_n):
                dst[k] = np.complex64(src[k])


@kernel
def interleave_groups(stack, bins, out, zero, add):
    """out[v, a, bins[g, j]] = stack[g, v, a, j] (``add``: +=, the groups in order), row by row
    of ``out`` (each row stays in cache while every group writes into it); ``zero``: each row
    zeroed first.

    :param stack: [G, V, A, J] complex64, C-contiguous; bins: [G, J] int64; out: [V, A, K]
        complex64
    """
    g_n, v_n, a_n, j_n = stack.shape
    for v in range(v_n):
        for a in range(a_n):
            dst = out[v, a]
            if zero:
                dst[:] = 0
            for g in range(g_n):
                src = stack[g, v, a]
                at = bins[g]
                if add:
                    for j in range(j_n):
                        dst[at[j]] += src[j]
                else:
                    for j in range(j_n):
                        dst[at[j]] = src[j]
