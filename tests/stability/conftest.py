"""One BLAS thread while the stability tests run.

They make thousands of small linear-algebra calls (4 x 4 eigendecompositions, 5 x 120 matrix
products); on the shared 2-core machine multithreaded OpenBLAS makes those ~7x slower (a chain
call: 1.1 s instead of 0.16 s), as ``benchmarks/bench_chain.py`` and the engine's
one-process-per-core executors already note. The environment variable cannot be set this late
(numpy is imported), so the thread count of numpy's and scipy's bundled OpenBLAS is set through
their own ``*_set_num_threads`` entry points (what threadpoolctl does) and restored afterwards.
Nothing happens where those libraries are not found.
"""

from __future__ import annotations

import ctypes
import glob
import os

import numpy
import pytest
import scipy

_ENTRY_POINTS = (("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                 ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
                 ("openblas_get_num_threads", "openblas_set_num_threads"))


def _openblas_controls() -> list[tuple]:
    out = []
    for module in (numpy, scipy):
        site = os.path.dirname(os.path.dirname(module.__file__))
        for path in glob.glob(os.path.join(site, f"{module.__name__}.libs", "lib*openblas*.so*")):
            try:
                lib = ctypes.CDLL(path)      # already loaded by the module: the same instance
            except OSError:
                continue
            for get, put in _ENTRY_POINTS:
                if hasattr(lib, get) and hasattr(lib, put):
                    getter, setter = getattr(lib, get), getattr(lib, put)
                    getter.restype, setter.argtypes = ctypes.c_int, [ctypes.c_int]
                    out.append((getter, setter))
                    break
    return out


@pytest.fixture(autouse=True, scope="package")
def _single_blas_thread():
    controls = _openblas_controls()
    before = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    yield
    for (_, put), n in zip(controls, before):
        put(n)
