"""Compiled kernels: Numba's ``njit``, applied at a kernel's first call.

The chain's per-RE and per-lag arithmetic (gather, multiply, accumulate, square and sum) written
in NumPy runs as a sequence of whole-array passes, each with its own temporary and dispatch; a
loop compiled by Numba (https://numba.readthedocs.io) fuses them into one pass. Numba is imported
and a kernel compiled only when the kernel is first called, so the CLI, a resume that computes
no chain and the tests that build no chain do not load it.

Compiled code is cached on disk (``cache=True``: beside the module, or in Numba's per-user
cache folder when that is not writable; ``NUMBA_CACHE_DIR`` moves it), so a run's worker
processes and later runs load it instead of compiling again. ``fastmath`` stays off: the loops'
products and sums are IEEE operations in the order written. They are not always NumPy's bits
(NumPy's SIMD complex product fuses a multiply and an add), so a kernel whose results differ from
the NumPy code it replaces in the last bits is a shortcut of :mod:`~veriloc_rt.phy.shortcuts`,
with the NumPy code kept as its reference path.

``NUMBA_DISABLE_JIT=1`` runs every kernel as plain Python (for debugging; very slow).
"""

from __future__ import annotations

import functools
import logging
import threading
import time

__all__ = ["first_calls", "kernel"]

log = logging.getLogger(__name__)

_LOCK = threading.Lock()
#: seconds of each kernel signature's first call in this process (compiled, or loaded from the
#: cache, plus one run), by kernel name, in call order
_FIRST: dict[str, list[float]] = {}
#: s: a call at least this long may have compiled or loaded a new signature (loading one from
#: the on-disk cache takes milliseconds; a compilation, a tenth of a second or more)
_NEW_SIGNATURE_S = 5e-4


def first_calls() -> dict[str, list[float]]:
    """The seconds of each kernel's new argument signatures' first calls in this process
    (compile or load from the on-disk cache, plus that call's run), by the kernel's qualified
    name: what a process pays before its kernels run (``benchmarks/bench_jit_compile.py``)."""
    with _LOCK:
        return {k: list(v) for k, v in _FIRST.items()}


def kernel(fn=None, **options):
    """Decorator: ``fn`` compiled by ``numba.njit(cache=True, nogil=True, **options)`` at its
    first call (Numba imported then). The wrapper keeps the plain function as ``py_func``.

    Each new argument signature compiles (or loads from the cache) at its first call, logged at
    DEBUG with its seconds and kept for :func:`first_calls`.
    """
    def wrap(f):
        compiled = None
        signatures = 0

        @functools.wraps(f)
        def call(*args):
            nonlocal compiled, signatures
            if compiled is None:
                with _LOCK:
                    if compiled is None:
                        import numba

                        compiled = numba.njit(cache=True, nogil=True, **options)(f)
            t = time.perf_counter()
            out = compiled(*args)
            dt = time.perf_counter() - t
            # a new signature (compiled, or loaded from the cache: milliseconds at least) adds
            # an overload; looked at only after a call that long, not on every call
            if dt > _NEW_SIGNATURE_S and len(getattr(compiled, "overloads", ())) != signatures:
                with _LOCK:
                    signatures = len(compiled.overloads)
                    _FIRST.setdefault(f.__qualname__, []).append(dt)
                log.debug("kernel %s: %.2f s (compiled or loaded for new argument types)",
                          f.__qualname__, dt)
            return out

        call.py_func = f
        return call

    return wrap if fn is None else wrap(fn)
