"""The benchmarks' instruments that decide what a bench reports: the machine-speed line's drift
(benchmarks/harness.py) and the native profile's classes (benchmarks/native_profile.py)."""

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[3] / "benchmarks"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def harness():
    return _load("harness")


@pytest.fixture(scope="module")
def native():
    return _load("native_profile")


def test_speed_line_gives_each_workloads_change_in_per_cent(harness):
    """(now / before - 1) x 100, rounded to a whole per cent, signed: 0.6 against 0.5 ms is
    +20 %, 3.0 against 4.0 is -25 %, equal values 0 (exact decimal arithmetic here; the
    formatting rounds half to even, which these values do not reach)."""
    before = {"fft": 0.5, "normals": 4.0, "grid pass": 0.6, "python": 2.0}
    now = {"fft": 0.6, "normals": 3.0, "grid pass": 0.6, "python": 2.2}
    line = harness.speed_line(now, before)
    assert line == ("machine: fft 0.6 ms (+20 %), normals 3 ms (-25 %), grid pass 0.6 ms (+0 %), "
                    "python 2.2 ms (+10 %)")
    assert harness.speed_line(now) == "machine: fft 0.6 ms, normals 3 ms, grid pass 0.6 ms, python 2.2 ms"


@pytest.mark.parametrize("frames,expected", [
    # the decoder's C++ calling libm's tanh: belief propagation, not libm
    (["ScenarioRunner.compute_chains (runner.py:247)", "NRLDPC.decode (ldpc.py:228)",
      "ldpc::bp::BpDecoder::bp_decode_parallel (bp.hpp:216)", "tanhf64 (libm.so.6)"], "bp"),
    # its code without symbols, which the innermost frame alone would call Numba's
    (["NRLDPC.decode (ldpc.py:228)", "0x7fc537a5e140 (ldpc/bp_decoder/_bp_decoder.cpython-311.so)",
      "0x7fc5545add3b (?)"], "bp"),
    # a module loaded during the profile: its own class, whatever runs innermost
    (["NRLDPC.decode (ldpc.py:162)", "_find_and_load (<frozen importlib._bootstrap>:1176)",
      "_compile_bytecode (<frozen importlib._bootstrap_external>:729)"], "imports"),
    # elsewhere the innermost frame decides, as before
    (["ToAEstimator.lag_power (toa.py:664)", "pocketfft::detail::pass4 (pypocketfft.so)"], "fft"),
    (["frequency_response (channel.py:251)", "cexpf64 (libm.so.6)"], "libm"),
])
def test_samples_are_classed_by_their_stack(native, frames, expected):
    """The class each stack must get, written out from the rules in the module's docstring."""
    names = {"bp": native.BP, "imports": native.IMPORTS, "fft": "FFT (pocketfft)",
             "libm": "libm (exp, sin, cos, tanh)"}
    assert native.classify_stack(frames) == names[expected]


def test_the_cold_runs_caches_and_home_are_the_benchs_own_and_start_empty(harness, tmp_path):
    """Every cache a new user's first run fills lies under the bench's folder, and
    ``empty=True`` removes what an earlier run left there (the cold run's premise)."""
    folder = tmp_path / "kernel-cache"
    (folder / "numba").mkdir(parents=True)
    (folder / "old.bin").write_bytes(b"kernel")
    (folder / "numba" / "old.nbi").write_bytes(b"index")
    env = harness.kernel_cache(folder, empty=True)
    assert not (folder / "old.bin").exists() and not (folder / "numba").exists()
    assert harness.kernel_count(folder) == 0
    for name in ("DRJIT_CACHE_DIR", "NUMBA_CACHE_DIR", "HOME", "XDG_CACHE_HOME", "XDG_CONFIG_HOME",
                 "MPLCONFIGDIR"):
        assert Path(env[name]).is_relative_to(folder.resolve()), name
    assert Path(env["HOME"]).is_dir()
    # kept (not emptied) without ``empty``: the warm run's kernels stay
    (folder / "new.bin").write_bytes(b"kernel")
    harness.kernel_cache(folder)
    assert harness.kernel_count(folder) == 1
