"""veriloc_rt.phy.jit: a kernel compiles at its first call, and computes what its Python does."""

from __future__ import annotations

import subprocess
import sys
import numpy as np

from veriloc_rt.phy.jit import first_calls, kernel

@kernel
def _weighted_sum(x, w):
    s = 0.0
    for i in range(x.size):
        s += x[i] * w[i]
    return s


def test_kernel_computes_its_python_function_in_order():
    # a sum in the order written: the same float64 additions as the plain Python loop (fastmath
    # off), exactly; np.dot may sum in another order, so it is compared to 1e-12 only
    rng = np.random.default_rng(3)
    x, w = rng.standard_normal(1001), rng.standard_normal(1001)
    assert _weighted_sum(x, w) == _weighted_sum.py_func(x, w)
    assert abs(_weighted_sum(x, w) - float(x @ w)) < 1e-12 * np.abs(x * w).sum()


def test_first_calls_counts_each_new_signature_once():
    # one entry per argument signature's first call (what the compile bench sums), none for a
    # repeated signature: float64 then float32 arrays add at most one entry each
    name = _weighted_sum.__qualname__
    x = np.arange(5.0)
    _weighted_sum(x, x)
    before = len(first_calls().get(name, []))
    assert before >= 1
    _weighted_sum(x, x)
    assert len(first_calls()[name]) == before
    y = x.astype(np.float32)
    _weighted_sum(y, y)
    _weighted_sum(y, y)
    assert len(first_calls()[name]) == before + 1
    assert all(s > 0 for s in first_calls()[name])


def test_numba_is_imported_at_the_first_kernel_call_only(tmp_path):
    # a file of its own (the on-disk cache needs the kernel's source file), run with -I
    script = tmp_path / "one_kernel.py"
    script.write_text("import sys\nfrom veriloc_rt.phy.jit import kernel\n\n"
                      "@kernel\ndef f(a):\n    return a + 1\n\n"
                      "before = 'numba' in sys.modules\nout = f(1)\n"
                      "print(before, 'numba' in sys.modules, out)\n")
    r = subprocess.run([sys.executable, "-I", str(script)], capture_output=True, text=True,
                       cwd=tmp_path, check=True)
    assert r.stdout.split() == ["False", "True", "2"]
