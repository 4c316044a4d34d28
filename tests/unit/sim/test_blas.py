"""The BLAS thread count set at run time (veriloc_rt.sim.blas).

Independent reference: OpenBLAS reads ``OPENBLAS_NUM_THREADS`` when it loads, so a process
started with the variable set to 1 must report 1 thread before anything is changed; and a
process started without it reports as many as OpenBLAS allows there (``os.cpu_count()``, at
most), which :func:`set_blas_threads` must bring down to 1.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from veriloc_rt.sim.blas import blas_threads, openblas_libraries, set_blas_threads

ROOT = Path(__file__).resolve().parents[3]

#: what the child process reports: threads per library before, the counts set_blas_threads
#: returned, and threads per library after one_blas_thread
PROBE = """\
import json, numpy, scipy.linalg
from veriloc_rt.sim.blas import blas_threads, one_blas_thread, set_blas_threads
before = blas_threads()
one_blas_thread()
print(json.dumps([before, blas_threads()]))
"""


def _probe(env_threads: str | None) -> tuple[dict, dict]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    env["PYTHONPATH"] = str(ROOT)
    if env_threads is not None:
        env["OPENBLAS_NUM_THREADS"] = env_threads
    r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env,
                       check=True)
    before, after = json.loads(r.stdout)
    return before, after


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_numpy_and_scipy_openblas_are_found():
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    libs = openblas_libraries()
    assert libs, "the NumPy and SciPy wheels each ship an OpenBLAS"
    assert set(blas_threads()) == set(libs)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_unpinned_process_is_brought_to_one_thread():
    before, after = _probe(None)
    assert before and all(1 <= n <= (os.cpu_count() or 1) for n in before.values())
    assert after == {p: 1 for p in before}
    before, after = _probe("1")
    assert before == after == {p: 1 for p in before}


def test_set_blas_threads_returns_the_previous_counts():
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    start = blas_threads()   # conftest.py pins BLAS to one thread before NumPy loads
    assert all(n == 1 for n in start.values())
    try:
        assert set_blas_threads(1) == start
        with pytest.raises(ValueError, match="`threads`"):
            set_blas_threads(0)
        with pytest.raises(ValueError, match="`threads`"):
            set_blas_threads(True)
    finally:
        set_blas_threads(1)
    assert blas_threads() == start
