"""One BLAS thread in a process the command line did not start (a Dask worker).

The command line pins BLAS to one thread before NumPy loads (``OPENBLAS_NUM_THREADS=1``), and
the run's numbers are those of one-thread BLAS: a multithreaded BLAS splits a reduction (a dot
product, a matrix product) among threads and sums the parts in another order, so its results
differ from one-thread BLAS in the last bits (the least-squares fits of the uplink position,
seen first, take another number of iterations). A process the command line did not start, a
``dask worker`` without a nanny among them, loads BLAS with as many threads as cores, where
the environment variable no longer helps: :func:`one_blas_thread` sets every loaded BLAS
library (NumPy's and SciPy's OpenBLAS, or another vendor's) to one thread through
``threadpoolctl``, once per process, for the tasks of a Dask cluster.
"""

from __future__ import annotations

import logging
import threading

log = logging.getLogger(__name__)

__all__ = ["blas_threads", "one_blas_thread"]

_LOCK = threading.Lock()
_PINNED = False


def blas_threads() -> dict[str, int]:
    """``{library path: threads}`` of the BLAS libraries loaded in this process."""
    from threadpoolctl import threadpool_info

    return {d["filepath"]: int(d["num_threads"]) for d in threadpool_info()
            if d.get("user_api") == "blas"}


def one_blas_thread() -> None:
    """Pin this process's BLAS to one thread, once (module docstring); later calls return at
    once. Logs what it changed; warns when no BLAS library is found."""
    global _PINNED
    with _LOCK:
        if _PINNED:
            return
        import numpy  # noqa: F401 - its BLAS must be loaded to be found
        import scipy.linalg  # noqa: F401
        from threadpoolctl import threadpool_limits

        before = blas_threads()
        threadpool_limits(limits=1, user_api="blas")
        _PINNED = True
    if not before:
        log.warning("no BLAS library found in this process: its thread count is left as it is "
                    "(results can differ from a one-thread run in the last bits)")
    elif any(n != 1 for n in before.values()):
        log.info("BLAS set to one thread (was %s)", ", ".join(
            f"{p}: {n}" for p, n in before.items()))
