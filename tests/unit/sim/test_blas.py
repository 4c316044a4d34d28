"""The BLAS thread count set at run time (veriloc_rt.sim.blas).

Independent reference: OpenBLAS reads ``OPENBLAS_NUM_THREADS`` when it loads, so a process
started with the variable set to 1 must report 1 thread before anything is changed; and a
process started without it reports as many as OpenBLAS allows there (``os.cpu_count()``, at
most), which :func:`one_blas_thread` must bring down to 1.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

#: what the child process reports: threads per library before and after one_blas_thread
PROBE = """\
import json, numpy, scipy.linalg
from veriloc_rt.sim.blas import blas_threads, one_blas_thread
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


def test_numpy_and_scipy_blas_are_found():
    from veriloc_rt.sim.blas import blas_threads

    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    # the NumPy and SciPy wheels each ship an OpenBLAS; conftest.py pins it to one thread
    threads = blas_threads()
    assert len(threads) >= 1 and all(n == 1 for n in threads.values())


def test_unpinned_process_is_brought_to_one_thread():
    before, after = _probe(None)
    assert before and all(1 <= n <= (os.cpu_count() or 1) for n in before.values())
    assert after == {p: 1 for p in before}
    before, after = _probe("1")
    assert before == after == {p: 1 for p in before}
