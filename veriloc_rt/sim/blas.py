"""The BLAS thread count of this process, set after NumPy and SciPy have loaded their BLAS.

The command line pins BLAS to one thread before NumPy loads (``OPENBLAS_NUM_THREADS=1``), and
the run's numbers are those of one-thread BLAS: a multithreaded BLAS splits a reduction (a dot
product, a matrix product) among threads and sums the parts in another order, so its results
differ from one-thread BLAS in the last bits (the least-squares fits of the uplink position,
seen first, take another number of iterations). A process the command line did not start, a
``dask worker`` without a nanny among them, loads BLAS with as many threads as cores, where
the environment variable no longer helps. :func:`set_blas_threads` sets the count of the
OpenBLAS libraries loaded in this process through their own ``openblas_set_num_threads`` (the
wheels of NumPy and SciPy each ship one, with prefixed symbols); :func:`one_blas_thread` does
so once per process, for the tasks of a Dask cluster.

Linux only (the loaded libraries are read from ``/proc/self/maps``); another BLAS (MKL,
Accelerate) is left as it is, with a warning.
"""

from __future__ import annotations

import ctypes
import logging
import threading
from pathlib import Path

log = logging.getLogger(__name__)

__all__ = ["openblas_libraries", "blas_threads", "set_blas_threads", "one_blas_thread"]

#: symbol names of OpenBLAS's thread count, as the builds name them: plain, SciPy's wheels
#: (``scipy_`` prefix) with 32-bit integers, NumPy's wheels with 64-bit integers (``64_``)
_SYMBOL_FORMS = ("{}", "scipy_{}", "scipy_{}64_", "{}64_")

_LOCK = threading.Lock()
_PINNED = False


def openblas_libraries() -> list[str]:
    """Paths of the OpenBLAS shared libraries mapped into this process (sorted)."""
    try:
        maps = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return []
    paths = {line.split(maxsplit=5)[5] for line in maps if len(line.split(maxsplit=5)) == 6}
    return sorted(p for p in paths if "openblas" in Path(p).name.lower() and ".so" in p)


def _function(lib: ctypes.CDLL, name: str):
    for form in _SYMBOL_FORMS:
        fn = getattr(lib, form.format(name), None)
        if fn is not None:
            return fn
    return None


def blas_threads() -> dict[str, int]:
    """``{library path: threads}`` of the loaded OpenBLAS libraries."""
    out = {}
    for path in openblas_libraries():
        get = _function(ctypes.CDLL(path), "openblas_get_num_threads")
        if get is not None:
            get.restype = ctypes.c_int
            out[path] = int(get())
    return out


def set_blas_threads(threads: int) -> dict[str, int]:
    """Set every loaded OpenBLAS library to ``threads`` threads -> ``{path: threads before}``.

    Not to be called while another thread of the process runs BLAS (OpenBLAS resizes its
    thread pool).
    """
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"Argument `threads` must be an integer >= 1, not {threads!r}")
    before = blas_threads()
    for path in before:
        lib = ctypes.CDLL(path)
        setter = _function(lib, "openblas_set_num_threads")
        # NumPy's 64-bit-integer build takes a 64-bit int
        setter.argtypes = [ctypes.c_int64 if "64_" in setter.__name__ else ctypes.c_int]
        setter.restype = None
        setter(threads)
    return before


def one_blas_thread() -> None:
    """Pin this process's OpenBLAS to one thread, once (module docstring); later calls return
    at once. Logs what it changed; warns when no OpenBLAS is loaded (another BLAS)."""
    global _PINNED
    with _LOCK:
        if _PINNED:
            return
        import numpy  # noqa: F401 - its BLAS must be loaded to be found
        import scipy.linalg  # noqa: F401

        before = set_blas_threads(1)
        _PINNED = True
    if not before:
        log.warning("no OpenBLAS loaded in this process: its BLAS thread count is left as it "
                    "is (results can differ from a one-thread run in the last bits)")
    elif any(n != 1 for n in before.values()):
        log.info("BLAS set to one thread (was %s)", ", ".join(
            f"{Path(p).name}: {n}" for p, n in before.items()))
