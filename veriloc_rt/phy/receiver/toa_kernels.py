"""Compiled kernels of the ToA search (:mod:`~veriloc_rt.phy.receiver.toa`): fused loops in place
of sequences of NumPy passes (:mod:`~veriloc_rt.phy.jit`, compiled at their first call).

Each kernel takes C-contiguous arrays of fixed dimensions (a caller reshapes), so that a chain
compiles few signatures. Each gives the NumPy code's bits (same operations, same order, same
precision; tests/unit/phy/receiver/test_toa_kernels.py compares them with ``np.array_equal``)
and replaces it outright.

Complex products: NumPy's SIMD loops on x86-64 with FMA (its AVX2 and AVX-512 paths, which it
picks on the machine this was measured on) compute (a_r + j a_i)(b_r + j b_i) as
``fma(a_r, b_r, -(a_i b_i))`` and ``fma(a_r, b_i, a_i b_r)``, a multiply and a fused
multiply-add per part; a plain loop's ``a * b`` rounds the two products separately.
:func:`multiply_into` calls :func:`fma` (LLVM's ``llvm.fma``, one rounding) in NumPy's order and
so gives its bits. Which rule this machine's NumPy follows is probed once per type
(:func:`numpy_product_rule`): without FMA the kernel rounds both products as NumPy then does.
"""

from __future__ import annotations

import threading
from fractions import Fraction

import numpy as np

from ..jit import kernel

__all__ = ["antenna_power", "cast_blocks", "fma", "interleave_groups", "multiply_into",
           "numpy_product_rule"]


def fma(a, b, c):
    """a * b + c rounded once, in the precision of the arguments (float32 or float64; all three
    of one type). In compiled kernels LLVM's ``llvm.fma``; this Python body (for
    ``NUMBA_DISABLE_JIT=1``) rounds the exact rational value to the nearest, ties to even."""
    t = type(a) if isinstance(a, np.floating) else np.float64
    if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c)):
        return t(a * b + c)      # inf or NaN: no rounding to get right
    exact = Fraction(float(a)) * Fraction(float(b)) + Fraction(float(c))
    x = t(float(exact))          # nearest double, then the type's: within one step of the nearest
    best = x
    for y in (np.nextafter(x, t(-np.inf)), np.nextafter(x, t(np.inf))):
        if np.isfinite(y):
            d, d0 = abs(Fraction(float(y)) - exact), abs(Fraction(float(best)) - exact)
            if d < d0 or (d == d0 and int(y.view(np.uint32 if t is np.float32 else np.uint64)) % 2 == 0):
                best = y
    return best


_FMA_LOCK = threading.Lock()
_FMA_READY = []


def _register_fma() -> None:
    """Numba's implementation of :func:`fma` (``llvm.fma`` on the arguments' float type),
    registered once, before the first kernel that calls it compiles (numba imported then)."""
    if _FMA_READY:
        return
    with _FMA_LOCK:
        if _FMA_READY:
            return
        from numba import types
        from numba.extending import intrinsic, overload

        @intrinsic
        def llvm_fma(typingctx, a, b, c):
            if not (isinstance(a, types.Float) and a == b == c):
                return None

            def codegen(context, builder, signature, args):
                return builder.fma(*args)

            return a(a, b, c), codegen

        @overload(fma)
        def fma_overload(a, b, c):
            if isinstance(a, types.Float) and a == b == c:
                return lambda a, b, c: llvm_fma(a, b, c)
            return None

        _FMA_READY.append(True)


@kernel
def _multiply_into(g, pre, out, fused):
    n_n, k_n = g.shape
    for n in range(n_n):
        src = g[n]
        dst = out[n]
        for k in range(k_n):
            a = src[k]
            b = pre[k]
            if fused:
                dst[k] = complex(fma(a.real, b.real, -(a.imag * b.imag)),
                                 fma(a.real, b.imag, a.imag * b.real))
            else:
                dst[k] = complex(a.real * b.real - a.imag * b.imag,
                                 a.real * b.imag + a.imag * b.real)


#: by complex dtype: True when NumPy's complex product fuses (module docstring), False when it
#: rounds both products, None when it is neither (:func:`numpy_product_rule`)
_RULES: dict = {}


def numpy_product_rule(dtype) -> bool | None:
    """How this machine's NumPy multiplies complex numbers of ``dtype``: True, each part as
    ``fma(a_r, b_r, -(a_i b_i))`` and ``fma(a_r, b_i, a_i b_r)`` (its SIMD loops with FMA);
    False, both products rounded, then added (without FMA); None, neither on a probe of 64
    products whose fused and unfused parts differ (kept per dtype)."""
    dtype = np.dtype(dtype)
    if dtype not in _RULES:
        rng = np.random.default_rng(0)
        t = dtype.type(0).real.dtype.type
        a = (rng.standard_normal(64) + 1j * rng.standard_normal(64)).astype(dtype)
        b = (rng.standard_normal(64) + 1j * rng.standard_normal(64)).astype(dtype)
        got = a * b
        fused = np.array([complex(fma(x.real, y.real, t(-(x.imag * y.imag))),
                                  fma(x.real, y.imag, t(x.imag * y.real))) for x, y in zip(a, b)],
                         dtype=dtype)
        plain = np.array([complex(t(x.real * y.real) - t(x.imag * y.imag),
                                  t(x.real * y.imag) + t(x.imag * y.real)) for x, y in zip(a, b)],
                         dtype=dtype)
        _RULES[dtype] = (True if np.array_equal(got, fused) and not np.array_equal(got, plain)
                         else False if np.array_equal(got, plain) else None)
    return _RULES[dtype]


def multiply_into(g, pre, out) -> None:
    """out[n, k] = g[n, k] pre[k] for k < K, rounded to out's precision: NumPy's
    ``np.multiply(g, pre, out=out[:, :K])`` bit for bit (its complex product as this machine's
    NumPy computes it, :func:`numpy_product_rule`; the product in g's precision, then cast as
    NumPy casts; NumPy itself when its rule is neither known one).

    :param g: [N, K] complex64 or complex128, C-contiguous; pre: [K] of g's dtype; out: [N, M]
        complex64 or complex128 (M >= K), C-contiguous
    """
    rule = numpy_product_rule(g.dtype)
    if rule is None:
        np.multiply(g, pre, out=out[:, :g.shape[1]])
        return
    if rule:
        _register_fma()
    _multiply_into(g, pre, out, rule)


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

