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

__all__ = ["kernel"]

log = logging.getLogger(__name__)

_LOCK = threading.Lock()


def kernel(fn=None, **options):
    """Decorator: ``fn`` compiled by ``numba.njit(cache=True, nogil=True, **options)`` at its
    first call (Numba imported then). The wrapper keeps the plain function as ``py_func``.

    Each new argument signature compiles (or loads from the cache) at its first call; calls
    that took longer than 0.2 s are logged at DEBUG with their seconds.
    """
    def wrap(f):
        compiled = None

        @functools.wraps(f)
        def call(*args):
            nonlocal compiled
            if compiled is None:
                with _LOCK:
                    if compiled is None:
                        import numba

                        compiled = numba.njit(cache=True, nogil=True, **options)(f)
            t = time.perf_counter()
            out = compiled(*args)
            dt = time.perf_counter() - t
            if dt > 0.2:
                log.debug("kernel %s: %.2f s (compiled or loaded for new argument types)",
                          f.__qualname__, dt)
            return out

        call.py_func = f
        return call

    return wrap if fn is None else wrap(fn)
