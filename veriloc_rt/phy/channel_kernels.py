"""Compiled kernels of the channel stage and the receiver's front end (:mod:`~veriloc_rt.phy.jit`).

Two kinds, by what they compute:

* exact: the same IEEE operations on the same operands as the NumPy code they replace (copies,
  placements, additions, real products), so the same bits; they replace it outright;
* fused products: complex products and sums in one compiled pass, rounded as written (NumPy's SIMD
  complex product fuses a multiply and an add, these do not), the shortcut ``jitchannel`` of
  :mod:`~veriloc_rt.phy.shortcuts`; the NumPy code is its reference path.

Every kernel takes C-contiguous arrays of fixed dtypes and dimensions (one compilation each).
"""

from __future__ import annotations

from .jit import kernel

__all__ = ["scatter_add"]


@kernel
def scatter_add(flat, idx, v):
    """``flat[a, idx[j]] += v[a, j]`` in place: the additions of NumPy's ``flat[:, idx] += v``
    (exact). ``idx`` holds no entry twice, each in ``[0, flat.shape[1])`` (the caller's check).

    :param flat: [A, N] complex128; idx: [n] int64; v: [A, n] complex128
    """
    for a in range(flat.shape[0]):
        fa = flat[a]
        va = v[a]
        for j in range(idx.size):
            i = idx[j]
            fa[i] = fa[i] + va[j]
