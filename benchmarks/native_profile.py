"""Where the per-point chains' CPU goes, by the native code that runs it: a sampling profile
(`py-spy <https://github.com/benfred/py-spy>`_, ``record --native``) of
``ScenarioRunner.compute_chains`` on a config's benign points and attack-window points, each
sample put in one class (:func:`classify_stack`: a module's first load, the tag decoder's belief
propagation wherever in it the sample lies, else by the innermost frame): the libraries' kernels
(normals, FFT, BLAS, Numba-compiled loops, libm, belief propagation, AES and signatures), NumPy's
own loops and dispatch, the C library's memory calls, and the interpreter.

This is what decides how far the chain can go without doing less arithmetic: the kernels do
work the results depend on value for value, NumPy's loops are the model's elementwise
arithmetic (fusable, not removable), the interpreter and dispatch are what batching points
could remove.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/native_profile.py [CONFIG] \\
        [--points 40] [--rate 100] [--py-spy PATH]

Needs ``py-spy`` (``pip install py-spy``; not a dependency of veriloc-rt) and permission to
read a child's memory (ptrace). The profiled child computes the chains of ``--points`` points
from the first quarter of the non-attack points and as many from the middle of the attack
window, after two warm-up points (kernels compiled or loaded, caches filled).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import collections  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import sys, tempfile
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import numpy as np
import harness
config = None if sys.argv[2] == "default" else sys.argv[2]
n = int(sys.argv[3])
r = harness.scenario_runner(config, None, Path(tempfile.mkdtemp()), changes={})
inside, outside = np.flatnonzero(r.window), np.flatnonzero(~r.window)
benign = list(outside[outside.size // 4:][:n])
window = list(inside[inside.size // 2:][:n])
import ldpc  # noqa: F401  - the tag decoder's, imported at its first decode: not a chain's cost
for i in benign[:1] + window[:1]:       # warm-up: kernels, replicas, kept plans
    r.compute_chains("none", int(i))
    r.clear_cache()

def benign_points():
    for i in benign:
        r.compute_chains("none", int(i))
        r.clear_cache()

def window_points():
    for i in window:
        r.compute_chains("none", int(i))
        r.clear_cache()

import time
for part in (benign_points, window_points):
    t = time.thread_time()
    part()
    print(part.__name__, time.thread_time() - t)
"""

#: the class of the tag decoder's belief propagation and the tags' cryptography
BP = "belief propagation, AES, Ed25519"
#: classes by the innermost frame's text (a function and its file or library), first match wins
CLASSES = (
    ("normals (NumPy's ziggurat, PCG64)", ("random_standard_normal", "ziggurat", "pcg64",
                                           "_generator.cpython", "bit_generator", "legacy_gauss",
                                           "random_standard_normal_fill")),
    ("FFT (pocketfft)", ("pocketfft",)),
    ("BLAS (OpenBLAS)", ("openblas", "cblas", "gemm", "gemv", "herk", "_dotblas")),
    ("compiled loops (Numba)", ("numba", "__numba", "_ZN0", "<numba", "_dispatcher.cpp")),
    ("libm (exp, sin, cos, tanh)", ("libm.so", "libm-", "__exp", "__sin", "__cos", "__tanh",
                                    "libmvec")),
    (BP, ("ldpc", "_rust.abi3", "libcrypto", "cryptography", "bp_decoder", "nacl", "ed25519")),
    ("NumPy loops and dispatch", ("_multiarray_umath", "numpy/_core", "numpy.core",
                                  "_umath_linalg", "npy_", "PyArray")),
    ("libc (memcpy, memset, allocation)", ("libc.so", "libc-", "memcpy", "memset", "malloc",
                                           "free (", "memmove", "mmap", "munmap", "ld-linux")),
)


#: the class of a sample taken while a module was being imported (once a process)
IMPORTS = "imports (a module's first load)"
#: native frames of the tag decoder's belief propagation (the ``ldpc`` package's C++, whose
#: calls of libm's tanh and code without symbols would otherwise count as libm and Numba)
BP_FRAMES = ("ldpc::", "bp_decoder")


def classify_stack(frames: list[str]) -> str:
    """The class of a sample from its whole stack: an import (any importlib frame), the tag
    decoder's belief propagation (any of :data:`BP_FRAMES`), else its innermost frame's
    (:func:`classify`)."""
    if any("importlib" in f or "_find_and_load" in f for f in frames):
        return IMPORTS
    if any(k in f for f in frames for k in BP_FRAMES):
        return BP
    return classify(frames[-1])


def classify(frame: str) -> str:
    if frame.startswith("0x") and frame.endswith("(?)"):
        return "compiled loops (Numba)"   # code without a symbol: Numba's, compiled at run time
    for name, keys in CLASSES:
        if any(k in frame for k in keys):
            return name
    if frame.endswith(".py)") or ".py:" in frame or "(<string>:" in frame:
        return "Python (interpreter)"
    if "python" in frame or "libpython" in frame or "Py" in frame.split(" ")[0]:
        return "Python (interpreter)"
    return "other native"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default="configs/paper-uma.json")
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--rate", type=int, default=100, help="samples a second")
    ap.add_argument("--py-spy", default=shutil.which("py-spy") or "py-spy")
    ap.add_argument("--show", type=int, default=0,
                    help="print this many of each class's most frequent frames")
    ap.add_argument("--raw", type=Path, help="keep py-spy's raw profile in this file")
    args = ap.parse_args()
    if shutil.which(args.py_spy) is None and not Path(args.py_spy).is_file():
        print(f"error: --py-spy: {args.py_spy} not found (pip install py-spy)", file=sys.stderr)
        return 2
    child = [sys.executable, "-c", CHILD, str(ROOT / "benchmarks"), args.config, str(args.points)]
    # the same points without the profiler: py-spy pauses the process for each native stack
    # (a few ms), which slows it and cools its caches; the slow-down is printed with the table
    plain = subprocess.run(child, cwd=ROOT, capture_output=True, text=True)
    if plain.returncode != 0:
        print(f"error: {args.config}: {(plain.stderr or plain.stdout).strip().splitlines()[-1:]}",
              file=sys.stderr)
        return 2
    alone = {line.split()[0]: float(line.split()[1]) for line in plain.stdout.splitlines()
             if line.split()[:1] in (["benign_points"], ["window_points"])}
    with tempfile.TemporaryDirectory(prefix="native_profile_") as tmp:
        raw = Path(tmp) / "raw.txt"
        cmd = [args.py_spy, "record", "--native", "-r", str(args.rate), "-f", "raw", "-o",
               str(raw), "--"] + child
        r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        if r.returncode != 0 or not raw.is_file():
            print(f"error: py-spy: {(r.stderr or r.stdout).strip().splitlines()[-1:]}",
                  file=sys.stderr)
            return 2
        counts = {part: collections.Counter() for part in ("benign_points", "window_points")}
        frames_of = collections.defaultdict(collections.Counter)
        for line in raw.read_text().splitlines():
            stack, _, n = line.rpartition(" ")
            frames = stack.split(";")
            part = next((p for p in counts if any(p in f for f in frames)), None)
            if part is None or not any("compute_chains" in f for f in frames):
                continue
            cls = classify_stack(frames)
            counts[part][cls] += int(n)
            frames_of[cls][frames[-1]] += int(n)
        if args.raw is not None:
            shutil.copyfile(raw, args.raw)
    names = [c for c, _ in CLASSES] + ["Python (interpreter)", "other native", IMPORTS]
    print(f"{args.config}: {args.points} benign and {args.points} attack-window points, "
          f"{args.rate} samples a second")
    print("| innermost frame | benign % | attack window % |")
    print("| --- | --- | --- |")
    tot = {p: max(sum(c.values()), 1) for p, c in counts.items()}
    for name in names:
        print(f"| {name} | {100 * counts['benign_points'][name] / tot['benign_points']:.1f} | "
              f"{100 * counts['window_points'][name] / tot['window_points']:.1f} |")
    print(f"| samples | {tot['benign_points']} | {tot['window_points']} |")
    print("| ms a point: unprofiled (thread CPU); profiled (samples / rate) | "
          + " | ".join(f"{1e3 * alone[p] / args.points:.0f}; {1e3 * tot[p] / args.rate / args.points:.0f}"
                       for p in ("benign_points", "window_points")) + " |")
    for name in names:
        for frame, n in frames_of[name].most_common(args.show):
            print(f"  {name}: {n} {frame}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
