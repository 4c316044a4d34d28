"""Compiled kernels of the channel stage (:mod:`~veriloc_rt.phy.jit`), by what they compute:

* exact, the same IEEE operations on the same operands as the NumPy code they replace, so its
  bits (replacing it outright): :func:`scatter_add` (a link's products added into the received
  grid), :func:`place_scaled` (the UE's noise normals scaled and placed on the REs read);
* fused products, the shortcut ``jitchannel`` of :mod:`~veriloc_rt.phy.shortcuts`:
  :func:`add_response_on`, :func:`add_response` (a one-delay link's response formed RE by RE
  and applied in the same pass), :func:`add_response_base` (that, plus a grid the link's signal
  is added to: the adversary's onto the benign one), complex products rounded as written
  (NumPy's SIMD complex product fuses a multiply and an add, these do not); the NumPy code is
  the reference path.

Every kernel takes C-contiguous arrays of fixed dtypes and dimensions (one compilation each).
"""

from __future__ import annotations

import numpy as np

from .jit import kernel

__all__ = ["add_response", "add_response_base", "add_response_on", "place_scaled", "scatter_add"]


@kernel
def scatter_add(flat, idx, v):
    """``flat[a, idx[j]] += v[a, j]`` in place: the additions of NumPy's ``flat[:, idx] += v``
    (exact). ``idx`` holds no entry twice, each in ``[0, flat.shape[1])`` (the index of a
    :class:`~veriloc_rt.phy.channel.REPlan` into the grid it was made for).

    :param flat: [A, N] complex128; idx: [n] int64; v: [A, n] complex128
    """
    for j in range(idx.size):   # RE by RE, the antennas inner: A streams through memory
        i = idx[j]
        for a in range(flat.shape[0]):
            flat[a, i] = flat[a, i] + v[a, j]


@kernel
def add_response_on(flat, idx, rows, cols, g, e_f, scale, x):
    """A link's products added into a received grid on the REs of its own (the shortcut
    ``jitchannel``), its response formed RE by RE from its factors:
    ``flat[a, idx[j]] += (h scale) x[idx[j]]`` with ``h = sum_u g[a, rows[j], u] e_f[cols[j], u]``
    (U >= 1 terms, summed in order); ``idx`` holds no entry twice.

    :param flat: [A, T K] complex128; idx, rows, cols: [n] int64, each RE's flat index, symbol
        and subcarrier
    :param g: [A, T, U] complex128, each distinct delay's gain at each symbol time
    :param e_f: [K, U] complex128, exp(-j 2 pi f_k (tau_u - t0)); x: [T K] complex128
    """
    num_u = g.shape[2]
    for j in range(idx.size):
        t = rows[j]
        k = cols[j]
        i = idx[j]
        xi = x[i]
        for a in range(flat.shape[0]):
            s = g[a, t, 0] * e_f[k, 0]
            for u in range(1, num_u):
                s += g[a, t, u] * e_f[k, u]
            flat[a, i] += (s * scale) * xi


@kernel
def add_response(flat, g, e_f, scale, x, first):
    """:func:`add_response_on` on every RE of the grid (a dense grid: a jammer's, the relay's):
    ``flat[a, t, k] += (h scale) x[t, k]``; ``first``: ``=`` (a grid not yet written, not read).
    flat: [A, T, K]; x: [T, K] complex128."""
    num_u = g.shape[2]
    for a in range(flat.shape[0]):
        for t in range(flat.shape[1]):
            fo = flat[a, t]
            ga = g[a, t]
            xt = x[t]
            if first:
                for k in range(fo.size):
                    s = ga[0] * e_f[k, 0]
                    for u in range(1, num_u):
                        s += ga[u] * e_f[k, u]
                    fo[k] = (s * scale) * xt[k]
            else:
                for k in range(fo.size):
                    s = ga[0] * e_f[k, 0]
                    for u in range(1, num_u):
                        s += ga[u] * e_f[k, u]
                    fo[k] += (s * scale) * xt[k]


@kernel
def add_response_base(flat, g, e_f, scale, x, base):
    """:func:`add_response` of a grid not yet written, plus ``base``, in the same pass:
    ``flat[a, t, k] = (h scale) x[t, k] + base[a, t, k]``, the bits of :func:`add_response`
    (``first``) followed by ``flat += base`` (the same product rounded to complex128, then the
    same addition; complex addition is exact to reorder). flat, base: [A, T, K] complex128;
    x: [T, K] complex128.

    A loop of its own rather than a mode of :func:`add_response`: one kernel with a run-time
    mode tested RE by RE measured 1.7-2.8x slower on a dense grid (``bench_jitchannel.py``)."""
    num_u = g.shape[2]
    for a in range(flat.shape[0]):
        for t in range(flat.shape[1]):
            fo = flat[a, t]
            bo = base[a, t]
            ga = g[a, t]
            xt = x[t]
            for k in range(fo.size):
                s = ga[0] * e_f[k, 0]
                for u in range(1, num_u):
                    s += ga[u] * e_f[k, u]
                fo[k] = (s * scale) * xt[k] + bo[k]


@kernel
def place_scaled(out, idx, z, scale, complex_scale):
    """Normals placed on a grid, 0 elsewhere: ``out[idx[j]] = (z[j, 0] + j z[j, 1]) scale``,
    every other entry of ``out`` 0 (written: ``out`` need not be zeroed), exact: the operations
    of NumPy's scaling, ``complex_scale`` that of the complex array ``n *= scale`` (a product
    by ``scale + 0j``: ``z0 scale - z1 0``, ``z0 0 + z1 scale``, whose terms in 0 are exact, so a
    fused multiply-add rounds them alike), else the float64 product of each part
    (``np.multiply(z, scale, dtype=float64)``).

    :param out: [N] complex128; idx: [n] int64, increasing, in [0, N)
    :param z: [n, 2] float64 or float32, the draws; scale: float64
    """
    i = 0
    for j in range(idx.size):
        while i < idx[j]:   # the gap before the next normal's RE
            out[i] = 0.0
            i += 1
        z0 = np.float64(z[j, 0])
        z1 = np.float64(z[j, 1])
        if complex_scale:
            out[i] = complex(z0 * scale - z1 * 0.0, z0 * 0.0 + z1 * scale)
        else:
            out[i] = complex(z0 * scale, z1 * scale)
        i += 1
    while i < out.size:
        out[i] = 0.0
        i += 1
